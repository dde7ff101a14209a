// The splat2tiles web viewer (viewer/web, wasm32 + wgpu on WebGL2) in headless Chromium, loaded
// from a running `splat2tiles view` at BASE_URL. Streams the tileset through a throttled network,
// turns away mid-download so in-flight tiles are paused (aborted), turns back so they resume with
// HTTP Range, waits until everything is resident, then screenshots the canvas. Prints one JSON
// object: the viewer's stats, HTTP statuses seen, console problems, the screenshot path.
//
// usage: node web_viewer.mjs BASE_URL --shot out.png [--width 480] [--height 360]
//          [--auto-view 0] [--levels best] [--throttle BYTES_PER_S] [--timeout SECONDS]
//          [--camera SPEC] [--max-sse PX] [--still] [--frame-interval MS]
// --still: no turning away and back, only wait until the view is settled (city parity checks).
// --frame-interval: every requestAnimationFrame callback waits MS first (a slow GPU, seconds per
// frame): what the client fetches between frames then shows in the responses.
// Exit 0 when the run finished (the caller judges what it measured), 1 when it did not.
import fs from 'node:fs';
import { finish, launch, problems, parseArgs } from './interop_harness.mjs';

const { pos, opt } = parseArgs(process.argv.slice(2));
if (pos.length !== 1 || !opt.shot) {
  console.error('usage: node web_viewer.mjs BASE_URL --shot out.png [--width W] [--height H] ...');
  process.exit(2);
}
const base = pos[0].endsWith('/') ? pos[0] : `${pos[0]}/`;
const width = Number(opt.width ?? 480);
const height = Number(opt.height ?? 360);
const timeoutMs = Number(opt.timeout ?? 150) * 1000;
const throttle = Number(opt.throttle ?? 120000);

const browser = await launch({ width, height });
const { page } = browser;
const out = { client: 'splat2tiles web viewer', ok: false, phases: [] };
const responses = [];
page.on('response', (r) => {
  const req = r.request();
  responses.push({
    url: r.url().replace(base, '/'),
    status: r.status(),
    range: req.headers()['range'] ?? null,
    ifRange: req.headers()['if-range'] ?? null,
  });
});
const stats = () => page.evaluate(() => window.splat2tiles.stats());
const waitFor = async (what, pred, ms) => {
  const t0 = Date.now();
  for (;;) {
    const s = await stats();
    if (pred(s)) {
      out.phases.push({ phase: what, seconds: (Date.now() - t0) / 1000, stats: s });
      return s;
    }
    if (Date.now() - t0 > ms) throw new Error(`timed out waiting for: ${what}; last stats ${JSON.stringify(s)}`);
    await page.waitForTimeout(100);
  }
};

try {
  const qs = new URLSearchParams({
    tileset: '/tileset.json',
    width: String(width),
    height: String(height),
    autoView: String(opt['auto-view'] ?? 0),
    levels: String(opt.levels ?? 'best'),
    clean: '1',
    hold: '1',
  });
  if (opt.camera) qs.set('camera', String(opt.camera));
  if (opt['max-sse']) qs.set('maxSse', String(opt['max-sse']));
  if (opt['frame-interval']) {
    await page.addInitScript((ms) => {
      const raf = window.requestAnimationFrame.bind(window);
      window.requestAnimationFrame = (cb) => setTimeout(() => raf(cb), ms);
    }, Number(opt['frame-interval']));
  }
  const t0 = Date.now();
  await page.goto(`${base}viewer/index.html?${qs}`);
  // The page and its wasm load at full speed; the throttle is set before streaming starts, with
  // no request in flight (Chromium stalls requests issued across a change of the conditions).
  await page.waitForFunction(() => window.splat2tilesStart || document.title.startsWith('error'), null, {
    timeout: Number(opt['start-timeout'] ?? 300) * 1000,
  });
  const cdp = await page.context().newCDPSession(page);
  await cdp.send('Network.enable');
  // Bandwidth and latency only (no loss): slow enough that tiles are mid-body when we turn away.
  await cdp.send('Network.emulateNetworkConditions', {
    offline: false,
    latency: 20,
    downloadThroughput: throttle,
    uploadThroughput: -1,
  });
  await page.evaluate(() => window.splat2tilesStart?.());
  // Start-up compiles the viewer's wasm (16 MB since the TCN's runtime joined it): on a loaded
  // 2-core CI box with several browsers at once that exceeded 60 s, so allow --start-timeout.
  await page.waitForFunction(() => window.splat2tiles || document.title.startsWith('error'), null, {
    timeout: Number(opt['start-timeout'] ?? 300) * 1000,
  });
  out.phases.push({ phase: 'viewer started', seconds: (Date.now() - t0) / 1000 });
  const title = await page.title();
  if (title.startsWith('error')) throw new Error(title);

  if (!opt.still) {
  // 1. Some tiles are complete while others are still in flight. Two complete tiles mean the
  //    root's subtree file has been read, so what is in flight belongs to the view's refined cut
  //    and is needed again after the turn back (a root paused before the subtree arrived is not:
  //    on a loaded CI machine that left nothing to resume).
  await waitFor(
    'tiles complete, tiles in flight',
    (s) => s.residentTiles >= 2 && s.pending > 0,
    timeoutMs,
  );
  // 2. Look the other way: the tiles that left the view are paused (their fetches aborted).
  await page.evaluate(() => window.splat2tiles.turn(180, 0));
  await waitFor('paused after turning away', (s) => s.paused > 0, 30000);
  // 3. Turn back (the throttle stays: Chromium stalls requests issued across a change of the
  //    emulated conditions): paused tiles resume with Range requests, all tiles complete.
  await page.evaluate(() => window.splat2tiles.turn(-180, 0));
  }
  out.final = await waitFor('settled', (s) => s.idle && s.settled && s.residentSplats > 0, timeoutMs);
  // settled: the last frame drew every tile at full opacity (no fade running); a moment more
  // so that frame has reached the page's compositor.
  await page.waitForTimeout(300);
  const png = await page.locator('#view').screenshot();
  fs.writeFileSync(opt.shot, png);
  out.info = await page.evaluate(() => window.splat2tiles.viewer.info());
  out.overlay = await page.evaluate(() => document.getElementById('overlay').textContent);
  out.ok = true;
} catch (e) {
  out.error = String(e?.message ?? e);
} finally {
  out.responses = responses;
  // Aborting a paused tile's fetch is the point of the exercise: Chromium reports it as a failed
  // request (net::ERR_ABORTED); those are listed apart, everything else is a problem.
  out.abortedRequests = browser.logs
    .filter((l) => l.type === 'requestfailed' && / net::ERR_ABORTED$/.test(l.text))
    .map((l) => l.text.replace(base, '/'));
  out.problems = problems(browser.logs, [/\/tiles\/\S+ net::ERR_ABORTED$/]);
  out.logs = browser.logs.slice(0, 60);
  await browser.close();
}
finish(out, out.ok ? 0 : 1);
