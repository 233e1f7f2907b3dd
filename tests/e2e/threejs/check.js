#!/usr/bin/env node
// Opens a .glb in three.js in headless Chromium (Debian's chromium, software WebGL through
// SwiftShader), driven by puppeteer-core (npm, installed globally by scripts/setup.sh, like
// three): serves page.html, three's modules and the .glb from a local HTTP server, calls
// window.fourdCheck and writes what it reports to OUT.json (positions in glTF axes, in the
// .glb's vertex order) and the render to OUT.png.
// usage: node check.js GLB CLIP FRAME CAMERA.json OUT.json OUT.png [--compressed]
//            [--texture IMAGE]   (drawn instead of the .glb's texture)
// Exits 1 on a failure, 77 when chromium or the npm packages are missing.
'use strict';
const fs = require('fs');
const path = require('path');
const { requireBrowser, serve, launch, collectErrors } = require('../browser.js');

const [glb, clip, frame, cameraFile, outJson, outPng] = process.argv.slice(2, 8);
const compressed = process.argv.includes('--compressed');
const textureAt = process.argv.indexOf('--texture');
const texture = textureAt > 0 ? process.argv[textureAt + 1] : null;
if (!outPng) {
  console.error('usage: node check.js GLB CLIP FRAME CAMERA.json OUT.json OUT.png [--compressed]');
  process.exit(2);
}
const browserPackages = requireBrowser();
const threeDir = path.join(browserPackages.root, 'three');
if (!fs.existsSync(path.join(threeDir, 'build', 'three.module.js'))) {
  console.log('SKIP: three is not installed (scripts/setup.sh installs it)');
  process.exit(77);
}
let server = null;

(async () => {
  server = await serve((url) => {
    if (url === '/page.html') return path.join(__dirname, 'page.html');
    if (url === '/model.glb') return glb;
    if (url === '/texture' && texture) return texture;
    if (url.startsWith('/three/')) return path.join(threeDir, path.normalize(url.slice(7)));
    return null;
  });
  const port = server.address().port;
  const started = Date.now();
  const browser = await launch(browserPackages);
  try {
    const page = await browser.newPage();
    const errors = collectErrors(page, false);
    await page.goto(`http://127.0.0.1:${port}/page.html`);
    await page.waitForFunction('window.fourdReady === true', { timeout: 30000 });
    const camera = JSON.parse(fs.readFileSync(cameraFile, 'utf8'));
    const result = await page.evaluate(
      (o) => window.fourdCheck(o),
      { glb: '/model.glb', clip, frame: Number(frame), camera, texture: texture && '/texture' });
    if (errors.length) throw new Error('page errors: ' + errors.join('; '));
    fs.writeFileSync(outPng, Buffer.from(result.png.split(',')[1], 'base64'));
    delete result.png;
    result.compressed = compressed;
    result.clip = clip;
    result.frame = Number(frame);
    result.texture = texture || 'the .glb\'s';
    fs.writeFileSync(outJson, JSON.stringify(result));
    console.log(`${result.client} in ${await browser.version()}: ${glb}: clips ` +
                `${result.clips.join(', ')}; ${result.targets} morph targets; ${clip} frame ${frame} ` +
                `at ${result.time.toFixed(4)} s: target ${result.max_weight_target} weighs ` +
                `${result.max_weight}, all weights sum to ${result.weight_sum}; ` +
                `${result.vertices} vertices; ${((Date.now() - started) / 1000).toFixed(1)} s`);
  } finally {
    await browser.close();
    server.close();
  }
})().catch((e) => {
  console.error(`check.js: ${e.stack || e}`);
  if (server) server.close();
  process.exit(1);
});
