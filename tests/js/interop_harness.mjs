// Shared pieces of the browser interop tests (interop_cesium.mjs, interop_3dtiles_renderer.mjs):
// a static file server on 127.0.0.1 with URL-prefix mounts, headless Chromium (Debian's
// /usr/bin/chromium, SwiftShader WebGL2, flags from HEADLESS.md) through playwright-core with
// every console message and page error captured, and a pixel count against the background.
import http from 'node:http';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { chromium } from 'playwright-core';

const TYPES = {
  '.html': 'text/html; charset=utf-8',
  '.js': 'text/javascript; charset=utf-8',
  '.mjs': 'text/javascript; charset=utf-8',
  '.cjs': 'text/javascript; charset=utf-8',
  '.json': 'application/json',
  '.css': 'text/css',
  '.wasm': 'application/wasm',
  '.glb': 'model/gltf-binary',
  '.subtree': 'application/octet-stream',
  '.png': 'image/png',
  '.svg': 'image/svg+xml',
  '.xml': 'application/xml',
};

// A 1x1 transparent PNG, served as /favicon.ico so Chromium logs no 404 for it.
const FAVICON = Buffer.from(
  'iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAQAAAC1HAwCAAAAC0lEQVR42mNkYAAAAAYAAjCB0C8AAAAASUVORK5CYII=',
  'base64',
);

/**
 * Serves `mounts` ({'/prefix/': '/abs/dir', ...}, longest prefix wins) on 127.0.0.1 at a free
 * port. Every 4xx answer is recorded in `misses` so a test can assert on it.
 */
export async function serve(mounts) {
  const prefixes = Object.keys(mounts).sort((a, b) => b.length - a.length);
  const misses = [];
  const requests = [];
  const server = http.createServer((req, res) => {
    const url = new URL(req.url, 'http://127.0.0.1');
    const p = decodeURIComponent(url.pathname);
    requests.push(p);
    if (p === '/favicon.ico') {
      res.writeHead(200, { 'content-type': 'image/png' });
      res.end(FAVICON);
      return;
    }
    const prefix = prefixes.find((m) => p.startsWith(m));
    const root = prefix && path.resolve(mounts[prefix]);
    const file = root && path.resolve(root, '.' + p.slice(prefix.length - 1));
    if (!file || !(file === root || file.startsWith(root + path.sep))) {
      misses.push(`403 ${p}`);
      res.writeHead(403).end();
      return;
    }
    fs.readFile(file, (err, data) => {
      if (err) {
        misses.push(`404 ${p}`);
        res.writeHead(404).end();
        return;
      }
      const type = TYPES[path.extname(file)] ?? 'application/octet-stream';
      res.writeHead(200, { 'content-type': type, 'cache-control': 'no-store' });
      res.end(data);
    });
  });
  await new Promise((ok) => server.listen(0, '127.0.0.1', ok));
  const base = `http://127.0.0.1:${server.address().port}`;
  return { base, misses, requests, close: () => new Promise((ok) => server.close(ok)) };
}

/** Headless Chromium with SwiftShader WebGL2; `logs` collects console lines and page errors. */
export async function launch({ width = 640, height = 480 } = {}) {
  const executablePath = process.env.CHROMIUM ?? '/usr/bin/chromium';
  if (!fs.existsSync(executablePath)) {
    throw new Error(`no Chromium at ${executablePath} (apt-get install chromium; or set CHROMIUM)`);
  }
  const profile = fs.mkdtempSync(path.join(os.tmpdir(), 'pw-interop-'));
  const ctx = await chromium.launchPersistentContext(profile, {
    executablePath,
    headless: true,
    viewport: { width, height },
    args: [
      '--no-sandbox',
      '--no-first-run',
      '--disable-background-networking',
      '--disable-component-update',
      '--disable-sync',
      '--disable-quic',
      '--disable-default-apps',
      '--disable-extensions',
      '--use-angle=swiftshader',
      '--enable-unsafe-swiftshader',
    ],
  });
  const page = ctx.pages()[0] ?? (await ctx.newPage());
  const logs = [];
  page.on('console', (m) => logs.push({ type: m.type(), text: m.text() }));
  page.on('pageerror', (e) => logs.push({ type: 'pageerror', text: String(e?.stack ?? e) }));
  page.on('requestfailed', (r) =>
    logs.push({ type: 'requestfailed', text: `${r.url()} ${r.failure()?.errorText}` }),
  );
  const close = async () => {
    await ctx.close();
    fs.rmSync(profile, { recursive: true, force: true });
  };
  return { page, logs, close };
}

/** Console errors, warnings and page errors; `allowed` holds regexes of justified ones. */
export function problems(logs, allowed = []) {
  return logs
    .filter((l) => ['error', 'pageerror', 'requestfailed', 'warning'].includes(l.type))
    .filter((l) => !allowed.some((re) => re.test(l.text)))
    .map((l) => `[${l.type}] ${l.text}`);
}

/** Parses "--key value" pairs (and bare "--flag") after the positional arguments. */
export function parseArgs(argv) {
  const pos = [];
  const opt = {};
  for (let i = 0; i < argv.length; i++) {
    if (argv[i].startsWith('--')) {
      const k = argv[i].slice(2);
      if (i + 1 < argv.length && !argv[i + 1].startsWith('--')) opt[k] = argv[++i];
      else opt[k] = true;
    } else pos.push(argv[i]);
  }
  return { pos, opt };
}

/**
 * Counts pixels of a PNG screenshot that differ from `bg` ([r,g,b]) by more than `threshold` in
 * some channel, decoding the PNG in the page (Chromium) so Node needs no image library.
 */
export async function foreground(page, png, bg, threshold) {
  return page.evaluate(
    async ({ b64, bg, threshold }) => {
      const bytes = Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
      const bmp = await createImageBitmap(new Blob([bytes], { type: 'image/png' }));
      const c = new OffscreenCanvas(bmp.width, bmp.height);
      const ctx = c.getContext('2d');
      ctx.drawImage(bmp, 0, 0);
      const px = ctx.getImageData(0, 0, bmp.width, bmp.height).data;
      let fg = 0;
      for (let i = 0; i < px.length; i += 4) {
        const d = Math.max(
          Math.abs(px[i] - bg[0]),
          Math.abs(px[i + 1] - bg[1]),
          Math.abs(px[i + 2] - bg[2]),
        );
        if (d > threshold) fg++;
      }
      return { pixels: px.length / 4, foreground: fg, foregroundFraction: fg / (px.length / 4) };
    },
    { b64: png.toString('base64'), bg, threshold },
  );
}

// Prints `out` as JSON and exits with `code` once stdout has taken all of it: `process.exit`
// straight after `console.log` cuts a piped stdout at 64 KiB.
export function finish(out, code) {
  process.stdout.write(JSON.stringify(out, null, 1) + '\n', () => process.exit(code));
}
