#!/usr/bin/env node
// Drives the web player (build/web: index.html, player.js, fourd_web.js/.wasm) in headless
// Chromium (Debian's, software WebGL through SwiftShader) with puppeteer-core (npm, installed
// globally by scripts/setup.sh): loads ASSET through the page's URL parameter, runs SCRIPT through
// window.fourd.runScript (positions of every RECORD_EVERY-th frame), draws frame FRAME through
// CAMERA.json (client_check camera) unlit on a transparent background, measures live play at
// 1280x720 for FPS_SECONDS and the runtime step benchmark. Writes OUT.json (summary, frames,
// world positions in our axes, fps, benchmark) and OUT.png (the render).
// usage: node check.js WEB_DIR ASSET SCRIPT CAMERA.json FRAME RECORD_EVERY FPS_SECONDS OUT.json OUT.png
//        [--screenshot PAGE.png]   (also a screenshot of the page as a user sees it)
// Exits 1 on a failure, 77 when chromium or puppeteer-core is missing.
'use strict';
const fs = require('fs');
const { runWebPlayer } = require('../browser.js');

const [webDir, asset, scriptFile, cameraFile, frame, recordEvery, fpsSeconds, outJson, outPng] =
  process.argv.slice(2, 11);
const shotAt = process.argv.indexOf('--screenshot');
const screenshot = shotAt > 0 ? process.argv[shotAt + 1] : null;
if (!outPng) {
  console.error('usage: node check.js WEB_DIR ASSET SCRIPT CAMERA.json FRAME RECORD_EVERY ' +
                'FPS_SECONDS OUT.json OUT.png [--screenshot PAGE.png]');
  process.exit(2);
}
runWebPlayer('check.js', webDir, asset, { width: 1280, height: 720, echo: true, timeout: 60000 },
             async ({ browser, page, errors, loadSeconds, info }) => {
  let pageShot = null;
  if (screenshot) {  // the page as a user sees it, after a second of play
    await new Promise((resolve) => setTimeout(resolve, 1500));
    await page.screenshot({ path: screenshot });
    pageShot = screenshot;
  }
  const fps = await page.evaluate((s) => window.fourd.measureFps(s, 1280, 720), Number(fpsSeconds));
  const benchmark = await page.evaluate(() => window.fourd.benchmark(10000, 1 / 60));
  const camera = JSON.parse(fs.readFileSync(cameraFile, 'utf8'));
  const run = await page.evaluate((o) => {
    const r = window.fourd.runScript(o.script, { recordEvery: o.every, showFrame: o.frame });
    const png = window.fourd.render({ camera: o.camera, unlit: true, width: o.camera.width,
                                      height: o.camera.height });
    return { summary: r.summary, frames: r.frames, positions: Array.from(r.positions), png };
  }, { script: fs.readFileSync(scriptFile, 'utf8'), every: Number(recordEvery),
       frame: Number(frame), camera });
  if (errors.length) throw new Error('page errors: ' + errors.join('; '));
  fs.writeFileSync(outPng, Buffer.from(run.png.split(',')[1], 'base64'));
  const result = { client: await browser.version(), info, load_seconds: loadSeconds,
                   summary: run.summary, frames: run.frames, vertices: info.vertices,
                   positions: run.positions, fps, benchmark, screenshot: pageShot };
  fs.writeFileSync(outJson, JSON.stringify(result));
  console.log(`web player in ${result.client}: ${info.name}, ${info.vertices} vertices, ` +
              `${info.textures.count} key textures, loaded in ${loadSeconds.toFixed(1)} s; script: ` +
              `${run.summary.frames} frames, ${run.summary.transitions} transitions, ` +
              `${run.frames.length} recorded; live at ${fps.width}x${fps.height}: ` +
              `${fps.fps.toFixed(1)} FPS, ${fps.frame_work_ms.toFixed(2)} ms of work per frame, ` +
              `runtime step ${(1000 * fps.step_ms).toFixed(1)} us; step benchmark ` +
              `${benchmark.mean_us.toFixed(1)} us per step (fastest of ${benchmark.rounds} runs of ` +
              `${benchmark.steps} steps)`);
});
