#!/usr/bin/env node
// Measures the web player (build/web) on any asset in headless Chromium (software WebGL), as
// check.js does on the tiny sample's: live play at a canvas size (window.fourd.measureFps) and
// the runtime step benchmark (window.fourd.benchmark). Prints one JSON object: the asset's info,
// its download size and load time, fps and benchmark. With --profile OUT.cpuprofile it also
// records the benchmark with Chromium's sampling profiler (open in Chromium's DevTools; function
// names need a module linked with --profiling-funcs). With --screenshot OUT.png it first saves
// the page as a user sees it after 3 s of play (docs/web.png is one, on the default sample).
// With --evict MB the benchmark writes that many megabytes between two steps (untimed), so
// that every step starts with cold caches as in live play (web_step_bench's EVICT_MB).
// usage: node measure.js WEB_DIR ASSET [--fps SECONDS] [--size WxH] [--steps N] [--evict MB]
//        [--profile OUT.cpuprofile] [--screenshot OUT.png]
// Exits 1 on a failure, 77 when chromium or puppeteer-core is missing.
'use strict';
const fs = require('fs');
const { runWebPlayer } = require('../browser.js');

const args = process.argv.slice(2);
function option(name, fallback) {
  const at = args.indexOf(name);
  return at >= 0 ? args[at + 1] : fallback;
}
const [webDir, asset] = args;
if (!asset || !fs.existsSync(asset)) {
  console.error('usage: node measure.js WEB_DIR ASSET [--fps SECONDS] [--size WxH] [--steps N] ' +
                '[--evict MB] [--profile OUT.cpuprofile] [--screenshot OUT.png]' +
                (asset ? `\nmeasure.js: ${asset}: no such file` : ''));
  process.exit(2);
}
const fpsSeconds = Number(option('--fps', '5'));
const [width, height] = option('--size', '1280x720').split('x').map(Number);
const steps = Number(option('--steps', '10000'));
const evictMb = Number(option('--evict', '0'));
const profile = option('--profile', null);
const screenshot = option('--screenshot', null);
runWebPlayer('measure.js', webDir, asset, { width, height, echo: false, timeout: 300000 },
             async ({ browser, page, errors, loadSeconds, info }) => {
  if (screenshot) {
    await new Promise((resolve) => setTimeout(resolve, 3000));
    await page.screenshot({ path: screenshot });
  }
  const fps = fpsSeconds > 0
    ? await page.evaluate((o) => window.fourd.measureFps(o.s, o.w, o.h),
                          { s: fpsSeconds, w: width, h: height })
    : null;
  let session = null;
  if (profile) {
    session = await page.target().createCDPSession();
    await session.send('Profiler.enable');
    await session.send('Profiler.setSamplingInterval', { interval: 100 });
    await session.send('Profiler.start');
  }
  const benchmark = steps > 0
    ? await page.evaluate((o) => window.fourd.benchmark(o.n, 1 / 60, o.mb), { n: steps, mb: evictMb })
    : null;
  if (session) {
    const { profile: p } = await session.send('Profiler.stop');
    fs.writeFileSync(profile, JSON.stringify(p));
  }
  if (errors.length) throw new Error('page errors: ' + errors.join('; '));
  if (fps) delete fps.state;
  console.log(JSON.stringify({ client: await browser.version(), asset,
                               download_bytes: fs.statSync(asset).size, load_seconds: loadSeconds,
                               vertices: info.vertices, textures: info.textures, fps,
                               benchmark }));
});
