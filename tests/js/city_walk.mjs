// The web viewer walking a city along a real head trace (trace_place.mjs) in headless Chromium,
// loaded from a running `splat2tiles view` at BASE_URL. The page replays the trace in real time
// (camera set at the trace's 12 Hz through window.splat2tiles.setCamera); every --sample seconds
// this script records the viewer's stats (resident splats, cache bytes against budgetMB, the
// renderer's GPU bytes by its own accounting of textures and buffers, wasm memory), the page's JS
// heap (CDP Performance.getMetrics) and the browser processes' memory (/proc PSS), and the frame
// count. Writes one CSV row per sample to --csv and prints a JSON summary.
//
// usage: node city_walk.mjs BASE_URL --trace CSV --csv OUT.csv [--budget-mb 256] [--width 320]
//          [--height 240] [--scale 20] [--eye 1.7] [--ground Z] [--max-sse 16] [--seconds S]
//          [--sample 1] [--timeout 300] [--shot PNG]
// --seconds: replay only the first S seconds of the trace. --ground: the city's ground height
// (default: the lowest z of the root box). Exit 0 when the walk ran to its end (the caller judges
// the numbers), 1 when it did not (crash, page error, no viewer), 2 on bad arguments.
import fs from 'node:fs';
import { finish, launch, problems, parseArgs } from './interop_harness.mjs';
import { browserMemory, machineLoad } from './browser_memory.mjs';
import { readTrace, placeTrace, pathLength, cityFrame } from './trace_place.mjs';

const { pos, opt } = parseArgs(process.argv.slice(2));
if (pos.length !== 1 || !opt.trace || !opt.csv) {
  console.error('usage: node city_walk.mjs BASE_URL --trace CSV --csv OUT.csv [--budget-mb MB] ...');
  process.exit(2);
}
const base = pos[0].endsWith('/') ? pos[0] : `${pos[0]}/`;
const num = (k, d) => {
  const v = Number(opt[k] ?? d);
  if (!Number.isFinite(v)) {
    console.error(`--${k}: not a number: ${opt[k]}`);
    process.exit(2);
  }
  return v;
};
const width = num('width', 320);
const height = num('height', 240);
const budgetMB = num('budget-mb', 256);
const sampleS = num('sample', 1);
const timeoutS = num('timeout', 300);

let poses;
let place;
try {
  const rows = readTrace(opt.trace);
  const tileset = await (await fetch(`${base}tileset.json`)).json();
  const frame = cityFrame(tileset);
  place = {
    cx: frame.cx,
    cy: frame.cy,
    ground: opt.ground !== undefined ? num('ground', 0) : frame.ground,
    eye: num('eye', 1.7),
    scale: num('scale', 20),
    transform: frame.transform,
  };
  poses = placeTrace(rows, place);
  if (opt.seconds !== undefined) {
    const s = num('seconds', 0);
    poses = poses.filter((p) => p.t <= s);
    if (poses.length < 2) throw new Error(`--seconds ${s}: fewer than 2 trace samples`);
  }
} catch (e) {
  console.error(`city_walk: ${e?.message ?? e}`);
  process.exit(2);
}
const walkS = poses[poses.length - 1].t;

const out = {
  client: 'splat2tiles web viewer',
  trace: opt.trace,
  placement: place,
  traceSeconds: walkS,
  pathMetres: pathLength(poses),
  budgetMB,
  canvas: [width, height],
  ok: false,
  crashed: false,
  loadAtStart: machineLoad(),
};
const browser = await launch({ width, height });
const { page } = browser;
page.on('crash', () => {
  out.crashed = true;
});
const COLUMNS = [
  't_s', 'trace_t_s', 'eye_x', 'eye_y', 'eye_z', 'frames', 'fps', 'resident_splats', 'drawn',
  'resident_tiles', 'cache_bytes', 'budget_bytes', 'gpu_bytes', 'renderer_cpu_bytes', 'wasm_bytes',
  'js_heap_used', 'js_heap_total', 'browser_pss', 'renderer_pss', 'gpu_process_pss', 'browser_rss',
  'pending', 'errors', 'bytes_received', 'load1',
];
const rows = [];
// Written as the run goes, so a run that dies still leaves its samples.
fs.writeFileSync(opt.csv, `${COLUMNS.join(',')}\n`);
try {
  const cdp = await page.context().newCDPSession(page);
  await cdp.send('Performance.enable');
  const qs = new URLSearchParams({
    tileset: '/tileset.json',
    width: String(width),
    height: String(height),
    budgetMB: String(budgetMB),
    maxSse: String(num('max-sse', 16)),
    camera: poses[0].spec,
    clean: '1',
  });
  const t0 = Date.now();
  await page.goto(`${base}viewer/index.html?${qs}`);
  await page.waitForFunction(() => window.splat2tiles || document.title.startsWith('error'), null, {
    timeout: 300000,
  });
  const title = await page.title();
  if (title.startsWith('error')) throw new Error(title);
  out.pageSeconds = (Date.now() - t0) / 1000;
  // The replay runs in the page so a slow frame does not delay the camera: each tick sets the
  // pose of the latest trace sample at or before the elapsed time.
  await page.evaluate(
    ({ poses }) => {
      const start = performance.now();
      let i = 0;
      window.walk = { i: 0, done: false, t: 0 };
      const id = setInterval(() => {
        const t = (performance.now() - start) / 1000;
        let j = i;
        while (j + 1 < poses.length && poses[j + 1].t <= t) j++;
        if (j !== i) window.splat2tiles.setCamera(poses[j].spec);
        i = j;
        window.walk = { i, done: j + 1 >= poses.length, t };
        if (window.walk.done) clearInterval(id);
      }, 1000 / 12);
    },
    { poses: poses.map((p) => ({ t: p.t, spec: p.spec })) },
  );
  const tw = Date.now();
  for (;;) {
    const [s, walk, m] = await Promise.all([
      page.evaluate(() => window.splat2tiles.stats()),
      page.evaluate(() => window.walk),
      cdp.send('Performance.getMetrics'),
    ]);
    const metric = (n) => m.metrics.find((x) => x.name === n)?.value ?? null;
    const mem = browserMemory();
    const p = poses[walk.i];
    rows.push([
      ((Date.now() - tw) / 1000).toFixed(2), walk.t.toFixed(2), ...p.eye.map((c) => c.toFixed(2)),
      s.frames, s.fps.toFixed(3), s.residentSplats, s.drawn, s.residentTiles, s.cacheBytes,
      s.budgetBytes, s.gpuBytes, s.rendererCpuBytes, s.wasmBytes, metric('JSHeapUsedSize'),
      metric('JSHeapTotalSize'), mem.total, mem.byType.renderer ?? 0, mem.byType['gpu-process'] ?? 0,
      mem.rss, s.pending, s.errors, s.bytesReceived, machineLoad().load1,
    ]);
    out.last = s;
    fs.appendFileSync(opt.csv, `${rows[rows.length - 1].join(',')}\n`);
    if (walk.done) break;
    if ((Date.now() - tw) / 1000 > walkS + timeoutS) throw new Error('the replay did not finish');
    await page.waitForTimeout(sampleS * 1000);
  }
  // A screenshot waits for a new frame: on a CPU rasteriser that can take long, so its failure
  // is recorded, not the walk's.
  if (opt.shot) {
    await page
      .locator('#view')
      .screenshot({ path: opt.shot, timeout: 120000 })
      .catch((e) => {
        out.shotError = String(e?.message ?? e);
      });
  }
  out.ok = true;
} catch (e) {
  out.error = String(e?.message ?? e);
} finally {
  out.samples = rows.length;
  const col = (name) => rows.map((r) => Number(r[COLUMNS.indexOf(name)]));
  const max = (name) => Math.max(0, ...col(name));
  const frames = col('frames');
  // Frames keep coming: the longest run of consecutive samples without a new frame.
  let stall = 0;
  let run = 0;
  for (let i = 1; i < frames.length; i++) {
    run = frames[i] > frames[i - 1] ? 0 : run + 1;
    stall = Math.max(stall, run);
  }
  out.framesDuringWalk = frames.length ? frames[frames.length - 1] - frames[0] : 0;
  out.longestStallSamples = stall;
  out.max = {
    residentSplats: max('resident_splats'),
    cacheBytes: max('cache_bytes'),
    gpuBytes: max('gpu_bytes'),
    wasmBytes: max('wasm_bytes'),
    jsHeapUsed: max('js_heap_used'),
    browserPss: max('browser_pss'),
    rendererPss: max('renderer_pss'),
    gpuProcessPss: max('gpu_process_pss'),
  };
  out.cacheWithinBudget = col('cache_bytes').every((c, i) => c <= col('budget_bytes')[i]);
  out.loadAtEnd = machineLoad();
  out.problems = problems(browser.logs, [/\/tiles\/\S+ net::ERR_ABORTED$/]);
  out.logs = browser.logs.slice(0, 40);
  await browser.close().catch(() => {});
}
if (out.crashed) out.ok = false;
finish(out, out.ok ? 0 : 1);
