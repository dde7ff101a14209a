// The learned trajectory predictor (TCN, `stream::learned`) in the web viewer: loads the viewer
// from a running `splat2tiles view` at BASE_URL with `predictor=tcn`, runs the committed model
// RUNS times in the page's wasm on a steady walk (`window.splat2tiles.tcnCheck`) and lets the
// client stream for a few seconds with it. Prints one JSON object: the check's answer (ms per 30 s
// prediction from the browser's clock, the advance predicted at 5 s), the viewer's stats, problems.
//
// usage: node web_tcn.mjs BASE_URL [--runs 30] [--timeout SECONDS]
// Exit 0 when the run finished (the caller judges what it measured), 1 when it did not.
import { finish, launch, problems, parseArgs } from './interop_harness.mjs';

const { pos, opt } = parseArgs(process.argv.slice(2));
if (pos.length !== 1) {
  console.error('usage: node web_tcn.mjs BASE_URL [--runs 30] [--timeout SECONDS]');
  process.exit(2);
}
const base = pos[0].endsWith('/') ? pos[0] : `${pos[0]}/`;
const runs = Number(opt.runs ?? 30);
const timeoutMs = Number(opt.timeout ?? 120) * 1000;

const browser = await launch({ width: 160, height: 120 });
const { page } = browser;
const out = { client: 'splat2tiles web viewer (tcn)', ok: false };
try {
  const qs = new URLSearchParams({
    tileset: '/tileset.json',
    width: '160',
    height: '120',
    predictor: 'tcn',
    clean: '1',
  });
  await page.goto(`${base}viewer/index.html?${qs}`);
  await page.waitForFunction(() => window.splat2tiles || document.title.startsWith('error'), null, {
    timeout: timeoutMs,
  });
  const title = await page.title();
  if (title.startsWith('error')) throw new Error(title);
  out.check = await page.evaluate((n) => window.splat2tiles.tcnCheck(n), runs);
  // The client plans with the TCN once it has 5 s of history: walk forward for 7 s.
  await page.keyboard.down('KeyW');
  await page.waitForTimeout(7000);
  await page.keyboard.up('KeyW');
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
