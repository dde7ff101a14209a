// A learned trajectory predictor (`stream::learned`: the TCN, or with `--predictor learned` the
// view model) in the web viewer: loads the viewer from a running `splat2tiles view` at BASE_URL
// with that predictor, runs the committed model RUNS times in the page's wasm on a steady walk
// (`window.splat2tiles.tcnCheck` / `learnedCheck`) and lets the
// client stream for a few seconds with it. Prints one JSON object: the check's answer (ms per 30 s
// prediction from the browser's clock, the advance predicted at 5 s), the viewer's stats, problems.
//
// usage: node web_tcn.mjs BASE_URL [--predictor tcn|learned] [--runs 30] [--timeout SECONDS]
// Exit 0 when the run finished (the caller judges what it measured), 1 when it did not.
import { finish, launch, problems, parseArgs } from './interop_harness.mjs';

const { pos, opt } = parseArgs(process.argv.slice(2));
if (pos.length !== 1) {
  console.error('usage: node web_tcn.mjs BASE_URL [--predictor tcn|learned] [--runs 30] [--timeout SECONDS]');
  process.exit(2);
}
const base = pos[0].endsWith('/') ? pos[0] : `${pos[0]}/`;
const runs = Number(opt.runs ?? 30);
const predictor = opt.predictor ?? 'tcn';
if (!['tcn', 'learned'].includes(predictor)) {
  console.error(`unknown predictor '${predictor}' (tcn, learned)`);
  process.exit(2);
}
const timeoutMs = Number(opt.timeout ?? 120) * 1000;

const browser = await launch({ width: 160, height: 120 });
const { page } = browser;
const out = { client: `splat2tiles web viewer (${predictor})`, ok: false };
try {
  const qs = new URLSearchParams({
    tileset: '/tileset.json',
    width: '160',
    height: '120',
    predictor,
    clean: '1',
  });
  await page.goto(`${base}viewer/index.html?${qs}`);
  await page.waitForFunction(() => window.splat2tiles || document.title.startsWith('error'), null, {
    timeout: timeoutMs,
  });
  const title = await page.title();
  if (title.startsWith('error')) throw new Error(title);
  out.check = await page.evaluate(
    ([n, p]) => (p === 'tcn' ? window.splat2tiles.tcnCheck(n) : window.splat2tiles.learnedCheck(n)),
    [runs, predictor],
  );
  // The client plans with the model once it has 5 s of history: walk forward for 7 s.
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
