// Frame rates and the split of a frame's time of lgvi view pages in headless chromium (SwiftShader), the pages
// taken in turn in every round so that pages compared share the machine's load (it is shared: report ratios):
//   node benchmarks/view_fps.mjs [--rounds R] [--frames K] [--seconds S] [--set JSON] PAGE.html [PAGE.html ...]
// --set: options for window.lgviView.set() before measuring, e.g. '{"follow": 5000, "distance": 40}' (a camera
// following body 5000 from 40 away: inside the benchmarks/view lattices).
// --pairs P: instead, the draw alone, finely interleaved: all pages open at once, and P times each page in turn
// draws 3 frames (profile(), at one of 10 times of the run's first third); prints per page the median draw (ms) and
// the median and quartiles of its ratio to the first page's draw of the same turn. The load of a shared machine
// changes within seconds: a round of the default mode (seconds per page) can fall in another load than its pair.
// Per page and round: the time to load it (to window.lgviView.ready), window.lgviView.profile(K, ...) (ms of the JS update, of which the instance matrices, and
// of the draw, waited for with a readPixels) and the frames per second of the page playing on its own
// (requestAnimationFrame) for S seconds. Prints, per page, the medians over rounds of the per-round medians, and
// a JSON line of everything.
import path from 'node:path';
import { launch, openView } from '../web/browser.mjs';

const args = process.argv.slice(2);
const option = (name, fallback) => {
  const i = args.indexOf(name);
  if (i < 0) return fallback;
  const value = Number(args[i + 1]);
  args.splice(i, 2);
  return value;
};
const rounds = option('--rounds', 3), frames = option('--frames', 10), seconds = option('--seconds', 10);
const setAt = args.indexOf('--set'), set = setAt < 0 ? null : JSON.parse(args.splice(setAt, 2)[1]);
const pairs = option('--pairs', 0);
const median = (xs) => { const s = [...xs].sort((a, b) => a - b), n = s.length; return n % 2 ? s[(n - 1) / 2] : (s[n / 2 - 1] + s[n / 2]) / 2; };

const results = Object.fromEntries(args.map((p) => [p, []]));
const browser = await launch();
if (pairs > 0) {
  try {
    const tabs = [];
    for (const page of args) {
      const { page: tab, problems } = await openView(browser, path.resolve(page), 960, 640, 600000);
      if (problems.length) throw new Error(`${page}: ${problems.join('; ')}`);
      if (set) await tab.evaluate((o) => window.lgviView.set(o), set);
      tabs.push(tab);
    }
    for (let i = 0; i < pairs; ++i)
      for (const [k, tab] of tabs.entries()) {
        await tab.bringToFront();
        results[args[k]].push(median(await tab.evaluate((j) => {
          const ts = window.lgviView.times, t0 = ts[0], t1 = ts[ts.length - 1];
          return window.lgviView.profile(3, t0 + (j % 10) * (t1 - t0) / 30, 1e-3 * (t1 - t0)).map((f) => f.draw);
        }, i)));
      }
  } finally {
    await browser.close();
  }
  const first = results[args[0]];
  for (const [page, draws] of Object.entries(results)) {
    const r = draws.map((d, i) => d / first[i]).sort((a, b) => a - b), q = (f) => r[Math.floor(f * (r.length - 1))];
    console.log(`${page}: draw ${median(draws).toPrecision(3)} ms, ratio to ${args[0]} ${median(r).toFixed(3)} ` +
                `(quartiles ${q(0.25).toFixed(3)} ${q(0.75).toFixed(3)}; ${pairs} turns)`);
  }
  console.log(JSON.stringify(results));
  process.exit(0);
}
try {
  for (let r = 0; r < rounds; ++r) {
    for (const page of args) {
      const opened = performance.now();
      const { page: tab, problems } = await openView(browser, path.resolve(page), 960, 640, 600000);
      const load = performance.now() - opened;  // from navigating to window.lgviView.ready
      if (problems.length) throw new Error(`${page}: ${problems.join('; ')}`);
      if (set) await tab.evaluate((o) => window.lgviView.set(o), set);
      const profile = await tab.evaluate((k) => {
        const ts = window.lgviView.times, t0 = ts[0], t1 = ts[ts.length - 1];
        return window.lgviView.profile ? window.lgviView.profile(k, t0, (t1 - t0) / (3 * k)) : null;
      }, frames);
      const n0 = await tab.evaluate(() => { window.lgviView.play(); return window.lgviView.renderedFrames; });
      await new Promise((done) => setTimeout(done, 1000 * seconds));
      const n1 = await tab.evaluate(() => { window.lgviView.pause(); return window.lgviView.renderedFrames; });
      const round = { load, fps: seconds > 0 ? (n1 - n0) / seconds : NaN };
      if (profile)
        for (const key of Object.keys(profile[0])) round[key] = median(profile.map((f) => f[key]));
      results[page].push(round);
      console.error(`round ${r + 1} ${page}: ${JSON.stringify(round)}`);
      await tab.close();
    }
  }
} finally {
  await browser.close();
}
for (const [page, rs] of Object.entries(results)) {
  const line = Object.keys(rs[0]).map((key) => `${key} ${median(rs.map((x) => x[key])).toPrecision(3)}`);
  console.log(`${page}: ${line.join(', ')} (medians of ${rounds} rounds; ms but fps)`);
}
console.log(JSON.stringify(results));
