// glTF interop matrix of one engine: serves a folder of tile glbs (one per variant, e.g.
// best.glb, high.glb, medium.glb, low.glb) and the engines from node_modules, loads each file in
// the engine's page (interop_three_glb.html: three.js GLTFLoader; interop_babylon_glb.html:
// Babylon.js) in headless Chromium (SwiftShader), and prints one JSON object: per file the
// page's result (splat objects and splats and the camera, or the loader's error), the console
// messages of that load and the foreground pixels of its screenshot (saved to --shots).
//
// usage: node interop_glb.mjs GLB_DIR --engine three|babylon [--shots DIR] [--timeout SECONDS]
// Exit 0 when every page finished (the caller judges what loaded), 1 when one did not.
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { finish, serve, launch, problems, parseArgs, foreground } from './interop_harness.mjs';

const here = path.dirname(fileURLToPath(import.meta.url));
const { pos, opt } = parseArgs(process.argv.slice(2));
const PAGES = {
  three: { page: 'interop_three_glb.html', client: 'three.js GLTFLoader' },
  babylon: { page: 'interop_babylon_glb.html', client: 'Babylon.js glTF loader' },
};
const engine = PAGES[opt.engine];
if (pos.length !== 1 || !engine) {
  console.error('usage: node interop_glb.mjs GLB_DIR --engine three|babylon [--shots DIR]');
  process.exit(2);
}
const timeoutMs = Number(opt.timeout ?? 80) * 1000;
const files = fs.readdirSync(pos[0]).filter((f) => f.endsWith('.glb')).sort();

const srv = await serve({
  '/three/': path.join(here, 'node_modules/three'),
  '/nm/': path.join(here, 'node_modules'),
  '/glb/': path.resolve(pos[0]),
  '/': here,
});
const browser = await launch({ width: 640, height: 480 });
const out = { client: engine.client, ok: true, files: {} };
try {
  for (const f of files) {
    const first = browser.logs.length;
    const one = { finished: false };
    try {
      await browser.page.goto(`${srv.base}/${engine.page}?file=/glb/${f}`);
      await browser.page.waitForFunction(() => document.title.startsWith('done:'), null, {
        timeout: timeoutMs,
        polling: 250,
      });
      one.finished = true;
      one.result = await browser.page.evaluate(() => window.RESULT);
      one.loaded = (await browser.page.title()) === 'done:ok';
      const png = await browser.page.screenshot();
      if (opt.shots) fs.writeFileSync(path.join(opt.shots, f.replace(/\.glb$/, '.png')), png);
      one.image = await foreground(browser.page, png, [26, 26, 26], 40);
    } catch (e) {
      one.error = String(e?.message ?? e);
      out.ok = false;
    }
    one.problems = problems(browser.logs.slice(first));
    out.files[f] = one;
  }
} finally {
  out.httpMisses = srv.misses;
  await browser.close();
  await srv.close();
}
finish(out, out.ok ? 0 : 1);
