// CesiumJS interop check: serves a splat2tiles tileset folder, the CesiumJS build from
// node_modules/cesium/Build/Cesium and interop_cesium.html on 127.0.0.1, opens the page in
// headless Chromium (SwiftShader), waits for the page's verdict and prints one JSON object:
// the page's measurements (tiles, splats drawn, foreground pixels), console problems, 404s.
//
// usage: node interop_cesium.mjs TILESET_DIR [--shot out.png] [--sse N] [--place lon,lat,h]
//                                [--pitch DEG]
//                                [--target lon,lat,h,range] [--max-frames N] [--timeout SECONDS]
// Exit 0 when the page finished (whatever it measured; the caller judges), 1 when it did not.
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { finish, serve, launch, problems, parseArgs } from './interop_harness.mjs';

const here = path.dirname(fileURLToPath(import.meta.url));
const { pos, opt } = parseArgs(process.argv.slice(2));
if (pos.length !== 1) {
  console.error('usage: node interop_cesium.mjs TILESET_DIR [--shot out.png] [--sse N] ...');
  process.exit(2);
}
const timeoutMs = Number(opt.timeout ?? 80) * 1000;

const srv = await serve({
  '/cesium/': path.join(here, 'node_modules/cesium/Build', opt.unminified ? 'CesiumUnminified' : 'Cesium'),
  '/tileset/': path.resolve(pos[0]),
  '/': here,
});
const browser = await launch({ width: 640, height: 480 });
const out = { client: 'CesiumJS', ok: false };
try {
  const qs = new URLSearchParams();
  if (opt.sse) qs.set('sse', opt.sse);
  if (opt.place) qs.set('place', opt.place);
  if (opt.pitch) qs.set('pitch', opt.pitch);
  if (opt.target) qs.set('target', opt.target);
  if (opt['max-frames']) qs.set('maxFrames', opt['max-frames']);
  await browser.page.goto(`${srv.base}/interop_cesium.html?${qs}`);
  await browser.page.waitForFunction(() => document.title.startsWith('done:'), null, {
    timeout: timeoutMs,
    polling: 250,
  });
  out.result = await browser.page.evaluate(() => window.RESULT);
  out.ok = (await browser.page.title()) === 'done:ok';
  if (opt.shot) await browser.page.screenshot({ path: opt.shot });
} catch (e) {
  out.error = String(e?.message ?? e);
  if (opt.shot) await browser.page.screenshot({ path: opt.shot }).catch(() => {});
} finally {
  out.problems = problems(browser.logs);
  out.logs = browser.logs.slice(0, 50);
  out.httpMisses = srv.misses;
  out.tileRequests = srv.requests.filter((r) => r.startsWith('/tileset/')).length;
  await browser.close();
  await srv.close();
}
finish(out, out.ok ? 0 : 1);
