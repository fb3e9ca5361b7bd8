// Drives a view.html in headless chromium for tests/view/test_view.py, which makes the assertions:
//   node view_check.mjs VIEW_HTML OUT_DIR PLAN_JSON
// PLAN_JSON: { "times": [t, ...], "seek": t, "set": {follow, distance, trails, axes}, "width": W, "height": H,
//              "inFrame": true if VIEW_HTML embeds the view in an iframe (a notebook's output) }
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
  const { page, view, problems } = await openView(browser, path.resolve(html), plan.width || 960, plan.height || 640,
    120000, !!plan.inFrame);
  const report = { problems };
  if (await view.evaluate(() => !!(window.lgviView && window.lgviView.ready))) {
    Object.assign(report, await view.evaluate(() => ({
      frames: lgviView.frames, rows: lgviView.rows, times: lgviView.times, colours: lgviView.colours,
      pole: lgviView.pole, box: lgviView.box, drawn: lgviView.drawn })));
    report.states = await view.evaluate((ts) => ts.map((t) => lgviView.state(t)), plan.times || []);
    await view.evaluate((o) => lgviView.set(Object.assign({ ui: false }, o)), plan.set || {});
    report.seekTime = await view.evaluate((t) => lgviView.seek(t), plan.seek);
    report.projection = await view.evaluate(() => lgviView.project());
    report.overlay = await view.evaluate(() => Object.fromEntries(['time', 'energy_error', 'quat_norm_error',
      'momentum_error', 'note'].map((id) => [id, document.getElementById(id).textContent])));
    await page.screenshot({ path: path.join(outDir, 'screenshot.png') });
    await view.evaluate(() => lgviView.set({ ui: true }));
    await page.screenshot({ path: path.join(outDir, 'screenshot-ui.png') });
    if (plan.fpsSeconds) {  // frames rendered per second while playing (requestAnimationFrame loop)
      const n0 = await view.evaluate(() => { lgviView.play(); return lgviView.renderedFrames; });
      await new Promise((r) => setTimeout(r, 1000 * plan.fpsSeconds));
      const n1 = await view.evaluate(() => { lgviView.pause(); return lgviView.renderedFrames; });
      report.fps = (n1 - n0) / plan.fpsSeconds;
    }
  }
  fs.writeFileSync(path.join(outDir, 'report.json'), JSON.stringify(report));
} finally {
  await browser.close();
}
