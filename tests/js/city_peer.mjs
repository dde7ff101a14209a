// The full-download peer of the city walk: city_peer.html (PlayCanvas engine) in the same headless
// Chromium setup as city_walk.mjs, given the whole city as one file, camera at the walk's first
// pose. Records its time to first frame (first canvas with a lit pixel, polled every 0.5 s), the
// page's JS heap, PlayCanvas's VRAM accounting and the browser processes' memory (/proc PSS) every
// --sample seconds, and how it ended: first frame, load error, page crash, page error, timeout, or
// the harness's memory guard (--max-gib of browser PSS, or less than --min-free-gib available on
// the machine: it is shared, so the run is stopped before the kernel's OOM killer picks a victim).
// After a first frame the trace is replayed like city_walk.mjs (--walk).
//
// usage: node city_peer.mjs CITY_FILE --tileset TILESET_JSON --trace CSV --csv OUT.csv
//          [--width 320] [--height 240] [--scale 20] [--eye 1.7] [--ground Z] [--timeout 600]
//          [--sample 1] [--max-gib 12] [--min-free-gib 3] [--walk] [--shot PNG]
// CITY_FILE: a .ply / .compressed.ply / .sog PlayCanvas loads; TILESET_JSON: the tiled city (for
// the placement of the trace, trace_place.mjs). Prints one JSON object. Exit 0 when the run was
// recorded whatever its outcome, 2 on bad arguments.
import fs from 'node:fs';
import http from 'node:http';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { finish, launch, problems, parseArgs } from './interop_harness.mjs';
import { browserMemory, machineLoad } from './browser_memory.mjs';
import { readTrace, placeTrace, cityFrame } from './trace_place.mjs';

const here = path.dirname(fileURLToPath(import.meta.url));
const { pos, opt } = parseArgs(process.argv.slice(2));
if (pos.length !== 1 || !opt.tileset || !opt.trace || !opt.csv) {
  console.error('usage: node city_peer.mjs CITY_FILE --tileset TILESET_JSON --trace CSV --csv OUT.csv ...');
  process.exit(2);
}
const num = (k, d) => {
  const v = Number(opt[k] ?? d);
  if (!Number.isFinite(v)) {
    console.error(`--${k}: not a number: ${opt[k]}`);
    process.exit(2);
  }
  return v;
};
const [width, height] = [num('width', 320), num('height', 240)];
const timeoutS = num('timeout', 600);
const sampleS = num('sample', 1);
const maxBytes = num('max-gib', 12) * 2 ** 30;
const minFree = num('min-free-gib', 3) * 2 ** 30;
const file = path.resolve(pos[0]);
let poses;
try {
  if (!fs.statSync(file).isFile()) throw new Error(`${file}: not a file`);
  const frame = cityFrame(JSON.parse(fs.readFileSync(opt.tileset, 'utf8')));
  poses = placeTrace(readTrace(opt.trace), {
    cx: frame.cx,
    cy: frame.cy,
    ground: opt.ground !== undefined ? num('ground', 0) : frame.ground,
    eye: num('eye', 1.7),
    scale: num('scale', 20),
  });
} catch (e) {
  console.error(`city_peer: ${e?.message ?? e}`);
  process.exit(2);
}

// Static files, streamed (the city file may be GBs): the page, the engine, the city.
const mounts = {
  '/city/': path.dirname(file),
  '/pc/': path.join(here, 'node_modules/playcanvas/build'),
  '/': here,
};
const TYPES = { '.html': 'text/html; charset=utf-8', '.mjs': 'text/javascript', '.js': 'text/javascript' };
const server = http.createServer((req, res) => {
  const p = decodeURIComponent(new URL(req.url, 'http://127.0.0.1').pathname);
  const prefix = Object.keys(mounts).find((m) => p.startsWith(m));
  const root = path.resolve(mounts[prefix]);
  const f = path.resolve(root, `.${p.slice(prefix.length - 1)}`);
  if (!f.startsWith(root + path.sep)) return res.writeHead(403).end();
  fs.stat(f, (err, st) => {
    if (err || !st.isFile()) return res.writeHead(404).end();
    res.writeHead(200, {
      'content-type': TYPES[path.extname(f)] ?? 'application/octet-stream',
      'content-length': st.size,
      'cache-control': 'no-store',
    });
    fs.createReadStream(f).pipe(res);
  });
});
await new Promise((ok) => server.listen(0, '127.0.0.1', ok));
const base = `http://127.0.0.1:${server.address().port}`;

const out = {
  client: 'PlayCanvas engine (full download)',
  engine: JSON.parse(fs.readFileSync(path.join(here, 'node_modules/playcanvas/package.json'), 'utf8')).version,
  file,
  fileBytes: fs.statSync(file).size,
  canvas: [width, height],
  outcome: null,
  loadAtStart: machineLoad(),
};
const COLUMNS = [
  't_s', 'phase', 'frames', 'vram_bytes', 'js_heap_used', 'js_heap_total', 'browser_pss',
  'renderer_pss', 'gpu_process_pss', 'browser_rss', 'mem_available', 'load1',
];
const rows = [];
// Written as the run goes, so a run that dies still leaves its samples.
fs.writeFileSync(opt.csv, `${COLUMNS.join(',')}\n`);
const browser = await launch({ width, height });
const { page } = browser;
let crashed = false;
page.on('crash', () => {
  crashed = true;
});
try {
  const cdp = await page.context().newCDPSession(page);
  await cdp.send('Performance.enable');
  const qs = new URLSearchParams({
    file: `/city/${path.basename(file)}`,
    width: String(width),
    height: String(height),
    fov: '50',
    pose: JSON.stringify(poses[0]),
  });
  const t0 = Date.now();
  await page.goto(`${base}/city_peer.html?${qs}`);
  let walkStart = null;
  for (;;) {
    const t = (Date.now() - t0) / 1000;
    if (crashed) {
      out.outcome = 'page crashed';
      break;
    }
    // Each probe may fail when the renderer died or hangs; the memory is read regardless.
    const evalOr = (f, d) =>
      Promise.race([page.evaluate(f).catch(() => d), new Promise((ok) => setTimeout(() => ok(d), 20000))]);
    const [peer, vram, m] = await Promise.all([
      evalOr(() => window.peer, null),
      evalOr(() => window.peerVram?.() ?? null, null),
      Promise.race([cdp.send('Performance.getMetrics').catch(() => null), new Promise((ok) => setTimeout(() => ok(null), 20000))]),
    ]);
    const metric = (n) => m?.metrics.find((x) => x.name === n)?.value ?? '';
    const mem = browserMemory();
    const load = machineLoad();
    rows.push([
      t.toFixed(2), peer?.phase ?? 'unresponsive', peer?.frames ?? '', vram ?? '', metric('JSHeapUsedSize'),
      metric('JSHeapTotalSize'), mem.total, mem.byType.renderer ?? 0, mem.byType['gpu-process'] ?? 0,
      mem.rss, load.memAvailable, load.load1,
    ]);
    if (peer) out.peer = peer;
    fs.appendFileSync(opt.csv, `${rows[rows.length - 1].join(',')}\n`);
    if (crashed) {
      out.outcome = 'page crashed';
      break;
    }
    if (peer?.phase === 'load failed') {
      out.outcome = 'load failed';
      break;
    }
    if (peer?.errors?.length && !peer.firstFrame) {
      out.outcome = 'page error';
      break;
    }
    if (mem.total > maxBytes) {
      out.outcome = `stopped by the harness: browser PSS ${(mem.total / 2 ** 30).toFixed(2)} GiB > --max-gib`;
      break;
    }
    if (load.memAvailable < minFree) {
      out.outcome = `stopped by the harness: machine memory available ${(load.memAvailable / 2 ** 30).toFixed(2)} GiB < --min-free-gib`;
      break;
    }
    if (peer?.firstFrame && !opt.walk) {
      out.outcome = 'first frame';
      break;
    }
    if (peer?.firstFrame && opt.walk) {
      if (walkStart === null) {
        walkStart = Date.now();
        await page.evaluate(({ poses }) => {
          const start = performance.now();
          window.walk = { done: false };
          const id = setInterval(() => {
            const s = (performance.now() - start) / 1000;
            let j = 0;
            while (j + 1 < poses.length && poses[j + 1].t <= s) j++;
            window.peerSetPose(poses[j]);
            if (j + 1 >= poses.length) {
              window.walk.done = true;
              clearInterval(id);
            }
          }, 1000 / 12);
        }, { poses });
      } else if (await evalOr(() => window.walk?.done, false)) {
        out.outcome = 'first frame, walked the trace';
        break;
      }
    }
    if (!peer?.firstFrame && t > timeoutS) {
      out.outcome = `no first frame within ${timeoutS} s (phase: ${peer?.phase ?? 'unresponsive'})`;
      break;
    }
    await new Promise((ok) => setTimeout(ok, sampleS * 1000));
  }
} catch (e) {
  out.outcome = `harness error: ${e?.message ?? e}`;
} finally {
  out.samples = rows.length;
  const col = (name) => rows.map((r) => Number(r[COLUMNS.indexOf(name)]) || 0);
  out.max = {
    vramBytes: Math.max(0, ...col('vram_bytes')),
    jsHeapUsed: Math.max(0, ...col('js_heap_used')),
    browserPss: Math.max(0, ...col('browser_pss')),
    rendererPss: Math.max(0, ...col('renderer_pss')),
    gpuProcessPss: Math.max(0, ...col('gpu_process_pss')),
  };
  out.timeToFirstFrameSeconds = out.peer?.firstFrame?.seconds ?? null;
  // The canvas as the page saw it at the first frame (a screenshot would wait for a new frame,
  // tens of seconds each on a CPU rasteriser at city scale).
  if (opt.shot && out.peer?.firstFrame && !crashed) {
    const url = await Promise.race([
      page.evaluate(() => window.peerShot).catch(() => null),
      new Promise((ok) => setTimeout(() => ok(null), 120000)),
    ]);
    if (typeof url === 'string' && url.startsWith('data:image/png;base64,')) {
      fs.writeFileSync(opt.shot, Buffer.from(url.slice(22), 'base64'));
    } else out.shotError = 'the page did not hand over its first frame';
  }
  out.loadAtEnd = machineLoad();
  // PlayCanvas aborts its first request for the file when it streams it (seen on the plant too).
  out.problems = problems(browser.logs, [/\/city\/\S+ net::ERR_ABORTED$/]);
  out.logs = browser.logs.slice(0, 40);
  await Promise.race([browser.close().catch(() => {}), new Promise((ok) => setTimeout(ok, 30000))]);
  server.close();
}
finish(out, 0);
