// Screenshot of the web viewer with its overlay (the README's picture): opens BASE_URL's viewer
// (a running `splat2tiles view`), waits until every wanted tile is resident and faded in, saves
// the page. usage: node web_screenshot.mjs BASE_URL --shot out.png [--width 960] [--height 540]
//   [--auto-view 0] [--timeout 180]
import fs from 'node:fs';
import { launch, problems, parseArgs } from './interop_harness.mjs';

const { pos, opt } = parseArgs(process.argv.slice(2));
if (pos.length !== 1 || !opt.shot) {
  console.error('usage: node web_screenshot.mjs BASE_URL --shot out.png [--width W] [--height H]');
  process.exit(2);
}
const base = pos[0].endsWith('/') ? pos[0] : `${pos[0]}/`;
const width = Number(opt.width ?? 960);
const height = Number(opt.height ?? 540);
const browser = await launch({ width, height });
let code = 1;
try {
  const qs = new URLSearchParams({ tileset: '/tileset.json', autoView: String(opt['auto-view'] ?? 0) });
  await browser.page.goto(`${base}viewer/index.html?${qs}`);
  await browser.page.waitForFunction(
    () => {
      const s = window.splat2tiles?.stats();
      return s && s.idle && s.settled && s.residentSplats > 0 && s.frames > 3;
    },
    null,
    { timeout: Number(opt.timeout ?? 180) * 1000, polling: 250 },
  );
  fs.writeFileSync(opt.shot, await browser.page.screenshot());
  console.log(JSON.stringify(await browser.page.evaluate(() => window.splat2tiles.stats())));
  code = problems(browser.logs).length === 0 ? 0 : 1;
  if (code) console.error(problems(browser.logs).join('\n'));
} catch (e) {
  console.error(`${e.message}\nlast stats: ${JSON.stringify(await browser.page.evaluate(() => window.splat2tiles?.stats()))}`);
  console.error(problems(browser.logs).join('\n'));
} finally {
  await browser.close();
}
process.exit(code);
