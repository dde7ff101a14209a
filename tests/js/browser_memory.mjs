// Memory of the headless Chromium this Node process started, read from /proc (Linux): every
// descendant process's proportional set size (PSS, shared pages split between sharers, so the sum
// is not double-counted), grouped by Chromium process type (browser, renderer, gpu-process, ...).
import fs from 'node:fs';

/** pid -> parent pid for every process /proc lets us read. */
function parents() {
  const ppid = new Map();
  for (const name of fs.readdirSync('/proc')) {
    if (!/^\d+$/.test(name)) continue;
    try {
      const stat = fs.readFileSync(`/proc/${name}/stat`, 'utf8');
      // "pid (comm) state ppid ...": comm may hold spaces and parentheses.
      const rest = stat.slice(stat.lastIndexOf(')') + 2).split(' ');
      ppid.set(Number(name), Number(rest[1]));
    } catch {
      // the process ended while we listed it
    }
  }
  return ppid;
}

/** Descendants of `root` (not `root` itself). */
function descendants(root) {
  const ppid = parents();
  const children = new Map();
  for (const [pid, parent] of ppid) {
    if (!children.has(parent)) children.set(parent, []);
    children.get(parent).push(pid);
  }
  const out = [];
  const stack = [...(children.get(root) ?? [])];
  while (stack.length) {
    const pid = stack.pop();
    out.push(pid);
    stack.push(...(children.get(pid) ?? []));
  }
  return out;
}

/** "renderer", "gpu-process", "utility", "zygote", or "browser" (no --type) for a Chromium pid. */
function chromiumType(pid) {
  // Chromium rewrites its children's command lines into one space-separated string.
  const cmd = fs.readFileSync(`/proc/${pid}/cmdline`, 'utf8').replaceAll('\0', ' ');
  if (!/chrom/i.test(cmd.split(' ')[0])) return null;
  const t = cmd.match(/ --type=([\w-]+)/);
  return t ? t[1] : 'browser';
}

/** kB value of `key` in a /proc status-like file, or 0. */
function kb(text, key) {
  const m = text.match(new RegExp(`^${key}:\\s+(\\d+) kB`, 'm'));
  return m ? Number(m[1]) * 1024 : 0;
}

/**
 * Bytes held by the Chromium processes below this Node process: `{ total, rss, byType }` where
 * `total` and `byType` are PSS sums and `rss` the plain RSS sum (pages shared between the
 * processes counted once per process). Processes that end while being read are skipped.
 */
export function browserMemory() {
  let total = 0;
  let rss = 0;
  const byType = {};
  for (const pid of descendants(process.pid)) {
    try {
      const type = chromiumType(pid);
      if (!type) continue;
      const pss = kb(fs.readFileSync(`/proc/${pid}/smaps_rollup`, 'utf8'), 'Pss');
      rss += kb(fs.readFileSync(`/proc/${pid}/status`, 'utf8'), 'VmRSS');
      total += pss;
      byType[type] = (byType[type] ?? 0) + pss;
    } catch {
      // ended meanwhile
    }
  }
  return { total, rss, byType };
}

/** Load average and this machine's available memory (for the record of each run). */
export function machineLoad() {
  const [l1, l5] = fs.readFileSync('/proc/loadavg', 'utf8').split(' ').map(Number);
  const mem = fs.readFileSync('/proc/meminfo', 'utf8');
  return { load1: l1, load5: l5, memAvailable: kb(mem, 'MemAvailable') };
}
