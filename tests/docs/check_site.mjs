// The documentation site in Debian's headless chromium (puppeteer-core from web/node_modules, as the view's
// tests; no browser download):
//   node tests/docs/check_site.mjs HTML_DIR
// Loads every HTML page of HTML_DIR (build/docs/html) from file:// and fails, naming the page, on
//   * a console error, a page error, a failed request, or a request that leaves the machine (not file:, data:,
//     blob:): the site works offline;
//   * an image that did not load (naturalWidth 0);
//   * an internal link (to a local .html, or a #anchor) whose file is missing or whose #anchor is no id (or
//     name) in that file;
// and checks that the search page (search.html?q=quaternion) lists at least one result.
// Exit status 0 when all holds, 1 otherwise (every problem printed); 2 on bad usage.
import fs from 'node:fs';
import path from 'node:path';
import { createRequire } from 'node:module';
import { fileURLToPath, pathToFileURL } from 'node:url';

const here = path.dirname(fileURLToPath(import.meta.url));
const source = path.resolve(here, '..', '..');
const require = createRequire(path.join(source, 'web', 'package.json'));
const puppeteer = require('puppeteer-core');

const root = process.argv[2] && path.resolve(process.argv[2]);
if (!root || !fs.existsSync(path.join(root, 'index.html'))) {
  console.error(`usage: node check_site.mjs HTML_DIR (with index.html); got ${process.argv[2]}`);
  process.exit(2);
}

function htmlFiles(dir) {
  const out = [];
  for (const e of fs.readdirSync(dir, { withFileTypes: true })) {
    const p = path.join(dir, e.name);
    if (e.isDirectory()) {
      if (!['_static', '_sources', '_images'].includes(e.name)) out.push(...htmlFiles(p));
    } else if (e.name.endsWith('.html')) out.push(p);
  }
  return out.sort();
}

const idsOf = new Map();  // file -> Set of ids and names in it
function ids(file) {
  if (!idsOf.has(file)) {
    const text = fs.readFileSync(file, 'utf8');
    const set = new Set();
    for (const m of text.matchAll(/\s(?:id|name)="([^"]*)"/g)) set.add(m[1]);
    idsOf.set(file, set);
  }
  return idsOf.get(file);
}

const pages = htmlFiles(root);
const problems = [];
let links = 0;
const browser = await puppeteer.launch({
  executablePath: process.env.LGVI_CHROMIUM || '/usr/bin/chromium', headless: true,
  args: ['--headless=new', '--no-sandbox'] });
try {
  const page = await browser.newPage();
  let current = '';
  page.on('console', (m) => { if (m.type() === 'error' || m.type() === 'assert') problems.push(`${current}: console ${m.type()}: ${m.text()}`); });
  page.on('pageerror', (e) => problems.push(`${current}: page error: ${e.message}`));
  page.on('requestfailed', (r) => problems.push(`${current}: request failed: ${r.url().slice(0, 160)}`));
  page.on('request', (r) => {
    if (!/^(file|data|blob|about):/.test(r.url())) problems.push(`${current}: network request: ${r.url().slice(0, 160)}`);
  });
  for (const file of pages) {
    current = path.relative(root, file);
    await page.goto(pathToFileURL(file).href, { waitUntil: 'load', timeout: 60000 });
    const found = await page.evaluate(() => ({
      hrefs: [...document.querySelectorAll('a[href]')].map((a) => a.href),
      images: [...document.images].map((i) => ({ src: i.src, ok: i.complete && i.naturalWidth > 0 })),
    }));
    for (const img of found.images) if (!img.ok) problems.push(`${current}: image did not load: ${img.src}`);
    for (const href of found.hrefs) {
      const url = new URL(href);
      if (url.protocol !== 'file:') continue;  // external links are not followed (the tests run offline)
      const target = decodeURIComponent(url.pathname);
      if (!target.endsWith('.html')) {
        if (!fs.existsSync(target)) problems.push(`${current}: link to a missing file: ${href}`);
        continue;
      }
      links++;
      if (!fs.existsSync(target)) {
        problems.push(`${current}: link to a missing page: ${href}`);
        continue;
      }
      const anchor = decodeURIComponent(url.hash.slice(1));
      if (anchor && !ids(target).has(anchor)) problems.push(`${current}: link to a missing anchor: ${path.relative(root, target)}#${anchor}`);
    }
  }
  // The search: Sphinx's searchtools.js loads searchindex.js and fills #search-results.
  current = 'search.html?q=quaternion';
  await page.goto(pathToFileURL(path.join(root, 'search.html')).href + '?q=quaternion', { waitUntil: 'load' });
  try {
    await page.waitForFunction(() => document.querySelectorAll('#search-results li').length > 0, { timeout: 30000 });
    const n = await page.evaluate(() => document.querySelectorAll('#search-results li').length);
    console.log(`docs site: search for "quaternion": ${n} results`);
  } catch (e) {
    problems.push(`${current}: no search result within 30 s (${e.message})`);
  }
} finally {
  await browser.close();
}
console.log(`docs site: ${pages.length} pages, ${links} internal links checked`);
if (problems.length) {
  for (const p of problems) console.error(`docs site: ${p}`);
  process.exit(1);
}
