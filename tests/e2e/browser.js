// What the browser tests share (threejs/check.js, web/check.js): Debian's chromium and the
// globally installed puppeteer-core (scripts/setup.sh), or exit 77 (skipped) without them; a
// local HTTP server for the page's files; headless Chromium with software WebGL (SwiftShader);
// the page's errors collected.
'use strict';
const fs = require('fs');
const http = require('http');
const path = require('path');
const { execSync } = require('child_process');

// The chromium executable and puppeteer-core; exits 77 when either is missing.
function requireBrowser() {
  const chromium = ['/usr/bin/chromium', '/usr/bin/chromium-browser'].find((p) => fs.existsSync(p));
  if (!chromium) {
    console.log('SKIP: chromium is not installed (scripts/setup.sh installs it)');
    process.exit(77);
  }
  const root = execSync('npm root -g').toString().trim();
  try {
    return { chromium, root, puppeteer: require(path.join(root, 'puppeteer-core')) };
  } catch (e) {
    console.log('SKIP: puppeteer-core is not installed (scripts/setup.sh installs it)');
    process.exit(77);
  }
}

const types = { '.html': 'text/html', '.js': 'text/javascript', '.wasm': 'application/wasm',
                '.glb': 'model/gltf-binary' };

// Serves on 127.0.0.1 (a free port) the file `route(url path)` names; 404 for null or a missing
// file. Resolves to the server.
function serve(route) {
  const server = http.createServer((req, res) => {
    const file = route(decodeURIComponent(req.url.split('?')[0]));
    if (!file || !fs.existsSync(file)) {
      res.writeHead(404);
      res.end();
      return;
    }
    // Cross-origin isolated, as scripts/serve_web.sh serves the page: performance.now() then
    // ticks in 5 us rather than 100 us steps (the HUD times single runtime steps with it).
    res.writeHead(200, { 'Content-Type': types[path.extname(file)] || 'application/octet-stream',
                         'Cross-Origin-Opener-Policy': 'same-origin',
                         'Cross-Origin-Embedder-Policy': 'require-corp' });
    fs.createReadStream(file).pipe(res);
  });
  return new Promise((resolve) => server.listen(0, '127.0.0.1', () => resolve(server)));
}

function launch({ puppeteer, chromium }) {
  return puppeteer.launch({
    executablePath: chromium,
    headless: true,
    args: ['--no-sandbox', '--disable-dev-shm-usage', '--use-gl=angle', '--use-angle=swiftshader',
           '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist'],
  });
}

// The page's uncaught errors, console errors and failed requests (a missing favicon aside);
// other console messages go to stdout when `echo` is set.
function collectErrors(page, echo) {
  const errors = [];
  page.on('pageerror', (e) => errors.push(e.message));
  page.on('console', (m) => {
    if (m.type() === 'error') {
      if (!m.text().startsWith('Failed to load resource')) errors.push(m.text());
    } else if (echo) {
      console.log(`page: ${m.text()}`);
    }
  });
  page.on('response', (r) => {
    if (r.status() >= 400 && !r.url().endsWith('/favicon.ico')) errors.push(`${r.status()} ${r.url()}`);
  });
  return errors;
}

// The web player's files (WEB_DIR: index.html, player.js, fourd_web.js/.wasm) and one asset
// served as /asset.fourd; resolves to the server.
function serveWebPlayer(webDir, asset) {
  return serve((url) => {
    if (url === '/asset.fourd') return asset;
    if (['/index.html', '/player.js', '/fourd_web.js', '/fourd_web.wasm'].includes(url)) {
      return path.join(webDir, url.slice(1));
    }
    return null;
  });
}

// Opens the web player of `server` (serveWebPlayer) in a new page of `browser` at width x
// height and waits until its asset is loaded (or `timeout` ms). Resolves to {page, errors (still
// collected), loadSeconds, info}; throws on a page error while loading.
async function openWebPlayer(browser, server, { width, height, echo, timeout }) {
  const page = await browser.newPage();
  await page.setViewport({ width, height });
  const errors = collectErrors(page, echo);
  const started = Date.now();
  await page.goto(`http://127.0.0.1:${server.address().port}/index.html?asset=/asset.fourd`);
  await page.waitForFunction('window.fourd && window.fourd.info && window.fourd.info()',
                             { timeout });
  if (errors.length) throw new Error('page errors: ' + errors.join('; '));
  const loadSeconds = (Date.now() - started) / 1000;
  return { page, errors, loadSeconds, info: await page.evaluate(() => window.fourd.info()) };
}

// The frame of a script that drives the web player: serves WEB_DIR and ASSET, opens the page
// (openWebPlayer `options`), runs `body({browser, page, errors, loadSeconds, info})`, closes the
// browser and the server. On an error prints it after `name` and exits 1; exits 77 without
// chromium or puppeteer-core.
function runWebPlayer(name, webDir, asset, options, body) {
  const packages = requireBrowser();
  let server = null;
  (async () => {
    server = await serveWebPlayer(webDir, asset);
    const browser = await launch(packages);
    try {
      await body({ browser, ...(await openWebPlayer(browser, server, options)) });
    } finally {
      await browser.close();
      server.close();
    }
  })().catch((e) => {
    console.error(`${name}: ${e.stack || e}`);
    if (server) server.close();
    process.exit(1);
  });
}

module.exports = { requireBrowser, serve, launch, collectErrors, runWebPlayer };
