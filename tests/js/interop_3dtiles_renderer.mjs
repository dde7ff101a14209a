// 3DTilesRendererJS interop check: serves a splat2tiles tileset folder, three.js and
// 3d-tiles-renderer from node_modules and interop_3dtiles_renderer.html on 127.0.0.1, opens the
// page in headless Chromium (SwiftShader), and prints one JSON object: the page's result
// (models loaded, GaussianSplat objects, load errors), foreground pixels of the screenshot,
// console problems and 404s.
//
// usage: node interop_3dtiles_renderer.mjs TILESET_DIR [--shot out.png] [--sse N]
//                                          [--max-frames N] [--timeout SECONDS]
// Exit 0 when the page finished (the caller judges what it measured), 1 when it did not.
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { finish, serve, launch, problems, parseArgs, foreground } from './interop_harness.mjs';

const here = path.dirname(fileURLToPath(import.meta.url));
const { pos, opt } = parseArgs(process.argv.slice(2));
if (pos.length !== 1) {
  console.error('usage: node interop_3dtiles_renderer.mjs TILESET_DIR [--shot out.png] ...');
  process.exit(2);
}
const timeoutMs = Number(opt.timeout ?? 80) * 1000;

const srv = await serve({
  '/three/': path.join(here, 'node_modules/three'),
  '/3dtr/': path.join(here, 'node_modules/3d-tiles-renderer'),
  '/tileset/': path.resolve(pos[0]),
  '/': here,
});
const browser = await launch({ width: 640, height: 480 });
const out = { client: '3DTilesRendererJS', ok: false };
try {
  const qs = new URLSearchParams();
  if (opt.sse) qs.set('sse', opt.sse);
  if (opt['max-frames']) qs.set('maxFrames', opt['max-frames']);
  await browser.page.goto(`${srv.base}/interop_3dtiles_renderer.html?${qs}`);
  await browser.page.waitForFunction(() => document.title.startsWith('done:'), null, {
    timeout: timeoutMs,
    polling: 250,
  });
  out.result = await browser.page.evaluate(() => window.RESULT);
  out.ok = (await browser.page.title()) === 'done:ok';
  const png = await browser.page.screenshot();
  if (opt.shot) fs.writeFileSync(opt.shot, png);
  out.image = await foreground(browser.page, png, [26, 26, 26], 40);
} catch (e) {
  out.error = String(e?.message ?? e);
} finally {
  out.problems = problems(browser.logs);
  out.logs = browser.logs.slice(0, 50);
  out.httpMisses = srv.misses;
  out.tileRequests = srv.requests.filter((r) => r.startsWith('/tileset/')).length;
  await browser.close();
  await srv.close();
}
finish(out, out.ok ? 0 : 1);
