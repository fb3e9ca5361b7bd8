// Drives a view.html in headless chromium for tests/view/test_view.py, which makes the assertions:
//   node view_check.mjs VIEW_HTML OUT_DIR PLAN_JSON
// PLAN_JSON: { "times": [t, ...], "seek": t, "set": {follow, distance, trails, axes}, "width": W, "height": H }
// Writes OUT_DIR/report.json ({ problems, frames, rows, times, states, projection, overlay, colours, pole, drawn,
// seekTime, fps })
// and OUT_DIR/screenshot.png (UI panels hidden: the bodies only) and OUT_DIR/screenshot-ui.png.
import fs from 'node:fs';
import path from 'node:path';
import { createRequire } from 'node:module';

const [html, outDir, planJson] = process.argv.slice(2);
const plan = JSON.parse(planJson);
// puppeteer-core lives in the source tree's web/node_modules (npm ci --prefix web).
const require = createRequire(import.meta.url);
const { launch, openView } = await import(path.resolve(path.dirname(require.resolve('./view_check.mjs')), '../../web/browser.mjs'));

const browser = await launch();
try {
  const { page, problems } = await openView(browser, path.resolve(html), plan.width || 960, plan.height || 640);
  const report = { problems };
  if (await page.evaluate(() => !!(window.lgviView && window.lgviView.ready))) {
    Object.assign(report, await page.evaluate(() => ({
      frames: lgviView.frames, rows: lgviView.rows, times: lgviView.times, colours: lgviView.colours,
      pole: lgviView.pole, drawn: lgviView.drawn })));
    report.states = await page.evaluate((ts) => ts.map((t) => lgviView.state(t)), plan.times || []);
    await page.evaluate((o) => lgviView.set(Object.assign({ ui: false }, o)), plan.set || {});
    report.seekTime = await page.evaluate((t) => lgviView.seek(t), plan.seek);
    report.projection = await page.evaluate(() => lgviView.project());
    report.overlay = await page.evaluate(() => Object.fromEntries(['time', 'energy_error', 'quat_norm_error',
      'momentum_error', 'note'].map((id) => [id, document.getElementById(id).textContent])));
    await page.screenshot({ path: path.join(outDir, 'screenshot.png') });
    await page.evaluate(() => lgviView.set({ ui: true }));
    await page.screenshot({ path: path.join(outDir, 'screenshot-ui.png') });
    if (plan.fpsSeconds) {  // frames rendered per second while playing (requestAnimationFrame loop)
      const n0 = await page.evaluate(() => { lgviView.play(); return lgviView.renderedFrames; });
      await new Promise((r) => setTimeout(r, 1000 * plan.fpsSeconds));
      const n1 = await page.evaluate(() => { lgviView.pause(); return lgviView.renderedFrames; });
      report.fps = (n1 - n0) / plan.fpsSeconds;
    }
  }
  fs.writeFileSync(path.join(outDir, 'report.json'), JSON.stringify(report));
} finally {
  await browser.close();
}
