// A layered tileset in the web viewer, pose by pose: opens BASE_URL's viewer (a running
// `splat2tiles view`) at the first camera of CAMERAS (a JSON array of `look-at:` specs), then for
// every camera sets it, waits until the viewer is idle and settled (every wanted layer resident,
// fades and late-layer ramps over) and saves the canvas as OUT/frame_NNNN.png. Prints JSON: ok,
// per frame the stats (layered, layerBlends, residentSplats, camera), and console problems.
// usage: node web_layered.mjs BASE_URL --cameras cams.json --out DIR --width W --height H
//   [--blend continuous|hard] [--max-sse 16] [--fov 50] [--timeout 60]
import fs from 'node:fs';
import path from 'node:path';
import { launch, problems, parseArgs } from './interop_harness.mjs';

const { pos, opt } = parseArgs(process.argv.slice(2));
if (pos.length !== 1 || !opt.cameras || !opt.out) {
  console.error('usage: node web_layered.mjs BASE_URL --cameras cams.json --out DIR [--width W] [--height H]');
  process.exit(2);
}
const base = pos[0].endsWith('/') ? pos[0] : `${pos[0]}/`;
const cams = JSON.parse(fs.readFileSync(opt.cameras, 'utf8'));
const width = Number(opt.width ?? 256);
const height = Number(opt.height ?? 144);
const timeout = Number(opt.timeout ?? 60) * 1000;
fs.mkdirSync(opt.out, { recursive: true });
const browser = await launch({ width, height });
const out = { ok: false, frames: [], problems: [] };
let code = 1;
try {
  const qs = new URLSearchParams({
    tileset: '/tileset.json',
    width: String(width),
    height: String(height),
    camera: cams[0],
    maxSse: String(opt['max-sse'] ?? 16),
    fov: String(opt.fov ?? 50),
    blend: String(opt.blend ?? 'continuous'),
    levels: 'best',
    clean: '1',
  });
  await browser.page.goto(`${base}viewer/index.html?${qs}`);
  await browser.page.waitForFunction(() => window.splat2tiles?.stats()?.ready, null, { timeout });
  for (const [k, cam] of cams.entries()) {
    await browser.page.evaluate((c) => window.splat2tiles.setCamera(c), cam);
    // Two frames after the camera change at least, then idle and settled.
    const f0 = await browser.page.evaluate(() => window.splat2tiles.stats().frames);
    await browser.page.waitForFunction(
      (f0) => {
        const s = window.splat2tiles.stats();
        return s.frames > f0 + 2 && s.idle && s.settled && s.residentSplats > 0;
      },
      f0,
      { timeout, polling: 50 },
    );
    const shot = path.join(opt.out, `frame_${String(k).padStart(4, '0')}.png`);
    fs.writeFileSync(shot, await browser.page.screenshot({ clip: { x: 0, y: 0, width, height } }));
    const s = await browser.page.evaluate(() => window.splat2tiles.stats());
    out.frames.push({
      shot,
      layered: s.layered,
      layerBlends: s.layerBlends,
      residentSplats: s.residentSplats,
      errors: s.errors,
      lastErrors: s.lastErrors,
      camera: s.camera,
    });
  }
  out.ok = true;
} catch (e) {
  out.error = `${e.message}; last stats: ${JSON.stringify(await browser.page.evaluate(() => window.splat2tiles?.stats()))}`;
} finally {
  // The client aborts (pauses) downloads it no longer wants first when the camera moves.
  out.problems = problems(browser.logs, [/\/tiles\/\S+ net::ERR_ABORTED$/]);
  await browser.close();
}
code = out.ok && out.problems.length === 0 ? 0 : 1;
console.log(JSON.stringify(out));
process.exit(code);
