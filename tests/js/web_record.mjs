// Camera-path recording in the web viewer: loads the viewer from a running `splat2tiles view` at
// BASE_URL (autoView=0, recording from the first frame), waits for the start camera, walks forward
// with W and turns by script, then reads `window.splat2tiles.recording()` (splat2tiles-trace CSV)
// and presses R, which stops the recording and downloads the same CSV. Prints one JSON object:
// the start camera (`stats().camera`), the recorded CSV, the downloaded CSV, stats and problems.
//
// usage: node web_record.mjs BASE_URL [--width 160] [--height 120] [--timeout SECONDS]
// Exit 0 when the run finished (the caller judges the path), 1 when it did not.
import fs from 'node:fs';
import { finish, launch, problems, parseArgs } from './interop_harness.mjs';

const { pos, opt } = parseArgs(process.argv.slice(2));
if (pos.length !== 1) {
  console.error('usage: node web_record.mjs BASE_URL [--width W] [--height H] [--timeout SECONDS]');
  process.exit(2);
}
const base = pos[0].endsWith('/') ? pos[0] : `${pos[0]}/`;
const width = Number(opt.width ?? 160);
const height = Number(opt.height ?? 120);
const timeoutMs = Number(opt.timeout ?? 120) * 1000;

const browser = await launch({ width, height });
const { page } = browser;
const out = { client: 'splat2tiles web viewer (record)', ok: false };
try {
  const qs = new URLSearchParams({
    tileset: '/tileset.json',
    width: String(width),
    height: String(height),
    autoView: '0',
  });
  await page.goto(`${base}viewer/index.html?${qs}`);
  await page.waitForFunction(() => window.splat2tiles || document.title.startsWith('error'), null, {
    timeout: timeoutMs,
  });
  const title = await page.title();
  if (title.startsWith('error')) throw new Error(title);
  // The start camera exists once the tileset is read; the recording starts with it.
  await page.waitForFunction(() => window.splat2tiles.stats().recordedPoses > 0, null, {
    timeout: timeoutMs,
  });
  out.startCamera = await page.evaluate(() => window.splat2tiles.stats().camera);
  // Frames are slow while the first tiles decode (SwiftShader): hold W until a frame has moved
  // the camera and 1 s more, then turn and wait for a frame drawn after the turn.
  const moved = (from) =>
    page.waitForFunction((c) => window.splat2tiles.stats().camera !== c, from, {
      timeout: timeoutMs,
    });
  await page.keyboard.down('KeyW');
  await moved(out.startCamera);
  await page.waitForTimeout(1000);
  await page.keyboard.up('KeyW');
  const walked = await page.evaluate(() => window.splat2tiles.stats().camera);
  const frames = await page.evaluate(() => window.splat2tiles.stats().frames);
  await page.evaluate(() => window.splat2tiles.turn(30, -10));
  await moved(walked);
  await page.waitForFunction((n) => window.splat2tiles.stats().frames > n + 1, frames, {
    timeout: timeoutMs,
  });
  out.csv = await page.evaluate(() => window.splat2tiles.recording());
  out.endCamera = await page.evaluate(() => window.splat2tiles.stats().camera);
  // R: the recording stops and its CSV is downloaded.
  const download = page.waitForEvent('download', { timeout: 10000 });
  await page.keyboard.press('KeyR');
  const file = await (await download).path();
  out.downloaded = fs.readFileSync(file, 'utf8');
  out.stats = await page.evaluate(() => window.splat2tiles.stats());
  out.ok = true;
} catch (e) {
  out.error = String(e?.message ?? e);
} finally {
  out.problems = problems(browser.logs);
  out.logs = browser.logs.slice(0, 40);
  await browser.close();
}
finish(out, out.ok ? 0 : 1);
