// Open an lgvi view.html in Debian's headless chromium (puppeteer-core; no browser download), recording
// every console error, page error and network request: the page must work offline from file://.
// Shared by web/movie.mjs (lgvi view --movie) and the browser test (tests/view/view_check.mjs).
import puppeteer from 'puppeteer-core';

export const CHROMIUM = process.env.LGVI_CHROMIUM || '/usr/bin/chromium';
// WebGL through SwiftShader (no GPU here); no sandbox: the tests run as root.
export const FLAGS = ['--headless=new', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--no-sandbox'];

export async function launch() {
  return puppeteer.launch({ executablePath: CHROMIUM, headless: true, args: FLAGS });
}

/** Opens file://HTML_PATH at width x height; resolves to { page, view, problems } once window.lgviView.ready.
 *  `view` is where the view runs: the page itself, or with `inFrame` the page's first iframe (a page that embeds
 *  the view, as a Jupyter notebook's output does). */
export async function openView(browser, htmlPath, width, height, timeoutMs = 120000, inFrame = false) {
  const page = await browser.newPage();
  const problems = [];
  page.on('console', (m) => { if (m.type() === 'error' || m.type() === 'assert') problems.push(`console ${m.type()}: ${m.text()}`); });
  page.on('pageerror', (e) => problems.push(`page error: ${e.message}`));
  page.on('requestfailed', (r) => problems.push(`request failed: ${r.url().slice(0, 120)}`));
  page.on('request', (r) => {
    const url = r.url();
    if (!/^(file|data|blob):/.test(url)) problems.push(`network request: ${url}`);
  });
  await page.setViewport({ width, height, deviceScaleFactor: 1 });
  await page.goto('file://' + htmlPath, { waitUntil: 'load', timeout: timeoutMs });
  let view = page;
  if (inFrame) {
    view = page.frames().find((f) => f !== page.mainFrame());
    if (!view) {
      problems.push('the page has no iframe');
      return { page, view: page, problems };
    }
  }
  try {
    await view.waitForFunction(() => window.lgviView && window.lgviView.ready, { timeout: timeoutMs });
  } catch (e) {
    problems.push(`window.lgviView never became ready: ${e.message}`);
  }
  return { page, view, problems };
}
