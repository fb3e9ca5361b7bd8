// lgvi view --movie: render COUNT frames of view.html, evenly over the run, as PNGs into FRAMES_DIR
// (then python/lgvi/viewer.py encodes them with ffmpeg).
//   node web/movie.mjs VIEW_HTML FRAMES_DIR COUNT WIDTH HEIGHT
import path from 'node:path';
import { launch, openView } from './browser.mjs';

const [html, dir, count, width, height] = process.argv.slice(2);
const browser = await launch();
let status = 0;
try {
  const { page, problems } = await openView(browser, path.resolve(html), Number(width), Number(height));
  const times = await page.evaluate(() => window.lgviView.times);
  const n = Number(count), t0 = times[0], t1 = times[times.length - 1];
  await page.evaluate(() => window.lgviView.set({ ui: true }));
  for (let i = 0; i < n; ++i) {
    await page.evaluate((t) => window.lgviView.seek(t), t0 + (t1 - t0) * i / Math.max(n - 1, 1));
    await page.screenshot({ path: path.join(dir, `frame${String(i).padStart(5, '0')}.png`) });
  }
  if (problems.length) {
    console.error(`lgvi view --movie: the page reported:\n  ${problems.join('\n  ')}`);
    status = 1;
  }
} finally {
  await browser.close();
}
process.exit(status);
