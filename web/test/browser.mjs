// The player page in a real browser (spec/web.md §5): headless Chromium (Debian's) driven by
// puppeteer-core. Serves the repository (web/test/serve.mjs, which logs every range it sends), loads
// web/index.html, opens FILE by URL, and checks:
//   - opening fetched the header, index and chunk framing, not the file (bytes from the server's log);
//   - playing 2 s draws frames; a seek to the end fetches only what the last keyframes need;
//   - the canvas at three times matches fmdec --preview of the same times (mean absolute
//     difference per channel ≤ TOLERANCE, 1.5 by default, and the share of pixels off by more than
//     64 ≤ 3%), while the canvas at the first time against the preview of the last differs by more
//     (the comparison can fail: a control);
//   - nothing was written to the console as an error, and no page error was thrown;
// and reports the decode time per frame inside the browser (the worker's fm_decoder_decode).
//   node web/test/browser.mjs --fmdec FMDEC --file FILE.fmv [--out DIR] [--tolerance 1.5] [--speed FILE2.fmv ...]
// --speed files are only timed: each opened, 60 frames decoded over its range, ms per frame.
// Exits 77 when chromium or puppeteer-core is missing, naming it.
import { execFileSync } from 'node:child_process';
import { existsSync, mkdirSync, readFileSync, statSync, writeFileSync } from 'node:fs';
import { createRequire } from 'node:module';
import { dirname, join, relative, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';
import { serve } from './serve.mjs';

const root = resolve(dirname(fileURLToPath(import.meta.url)), '..', '..');
const args = process.argv.slice(2);
const option = (name, fallback = null) => {
  const i = args.indexOf(name);
  return i >= 0 ? args[i + 1] : fallback;
};
const speedFiles = args.flatMap((a, i) => (args[i - 1] === '--speed' ? [a] : []));
const fmdec = option('--fmdec');
const file = resolve(option('--file', join(root, 'tests/data/golden_v2_1.fmv')));
const out = resolve(option('--out', join(root, 'build-web/browser-test')));
const tolerance = Number(option('--tolerance', '1.5'));
mkdirSync(out, { recursive: true });

const chromium = ['/usr/bin/chromium', '/usr/bin/chromium-browser'].find((p) => existsSync(p));
if (!chromium) {
  console.log('SKIPPED: chromium not found (tools/install-deps.sh installs it)');
  process.exit(77);
}
const npmDir = resolve(root, process.env.FACEMORPH_NPM_DIR || 'build-web/npm');
let puppeteer;
try {
  puppeteer = createRequire(join(npmDir, 'package.json'))('puppeteer-core');
} catch {
  console.log(`SKIPPED: puppeteer-core not found in ${npmDir} (web/install-npm.sh installs it)`);
  process.exit(77);
}

const failures = [];
const check = (ok, what) => {
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${what}`);
  if (!ok) failures.push(what);
};

const { server, url, log } = await serve(root);
const browser = await puppeteer.launch({
  executablePath: chromium,
  headless: true,
  // WebGL without a GPU: SwiftShader, as a CI machine has it.
  args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist'],
});
const consoleErrors = [];
try {
  const page = await browser.newPage();
  await page.setViewport({ width: 800, height: 1000 });
  page.on('console', (message) => {
    if (message.type() === 'error') consoleErrors.push(message.text());
  });
  page.on('pageerror', (error) => consoleErrors.push(String(error)));
  await page.goto(`${url}/web/index.html`, { waitUntil: 'load' });
  await page.waitForFunction(() => window.facemorphPage && window.facemorphPage.ready, { timeout: 30000 });

  const fileUrl = '/' + relative(root, file);
  const fileBytes = statSync(file).size;
  const fmvBytes = () => log.filter((e) => e.path === fileUrl).reduce((sum, e) => sum + e.bytes, 0);
  const info = await page.evaluate((u) => window.facemorphPage.open(u), fileUrl);
  const stats = await page.evaluate(() => window.facemorphPage.stats());
  const atOpen = fmvBytes();
  console.log(`opened ${fileUrl}: N = ${info.gridN}, ${info.keyframeCount} keyframes in ${stats.open.groups} groups, texture ${info.textureSize}; ` +
              `${stats.open.requests} requests, ${stats.open.bytesFetched} bytes to open, ${atOpen} of ${fileBytes} bytes by the first frame (server's log)`);
  check(stats.open.bytesFetched < fileBytes || stats.open.groups === 0, `opening fetched ${stats.open.bytesFetched} bytes, less than the file's ${fileBytes}`);
  // The first frame (keys 0 .. 3 at most) needed only the groups holding them on top of that.
  const firstGroups = stats.open.groupRanges.filter((g) => g.first <= 3);
  const firstBytes = firstGroups.reduce((sum, g) => sum + g.end - g.begin, 0);
  check(atOpen <= stats.open.bytesFetched + firstBytes, `playback started after ${atOpen} bytes: the open's ${stats.open.bytesFetched} and at most ` +
        `the first frame's ${firstGroups.length} of ${stats.open.groups} groups (${firstBytes} bytes)`);

  // Play 2 s.
  const drawnBefore = stats.drawn;
  await page.evaluate(() => window.facemorphPage.play());
  await new Promise((r) => setTimeout(r, 2000));
  await page.evaluate(() => window.facemorphPage.pause());
  const played = await page.evaluate(() => window.facemorphPage.stats());
  // The rate is the machine's (headless Chromium draws with SwiftShader, on the CPU): reported, and
  // only required to have moved.
  check(played.drawn - drawnBefore >= 2, `playing 2 s drew ${played.drawn - drawnBefore} frames (${((played.drawn - drawnBefore) / 2).toFixed(1)} fps drawn)`);

  // A seek to the end fetches only the groups of the keyframes the end's frame may blend (the last
  // four: stream.js fetches keys i - 3 .. i + 3): every range the server sent for it lies in them.
  const logBefore = log.length;
  await page.evaluate((t) => window.facemorphPage.seek(t), info.rangeEnd);
  const seekRanges = log.slice(logBefore).filter((e) => e.path === fileUrl && e.range);
  const groups = stats.open.groupRanges;
  const needed = groups.filter((g, i) => (i + 1 < groups.length ? groups[i + 1].first : info.keyframeCount) > info.keyframeCount - 4);
  const inNeeded = seekRanges.every(({ range: [b, e] }) => needed.some((g) => g.begin <= b && e <= g.end));
  const seekBytes = seekRanges.reduce((sum, e) => sum + e.bytes, 0);
  check(inNeeded, `a seek to the end (t = ${info.rangeEnd.toFixed(3)} s) fetched ${seekBytes} bytes in ${seekRanges.length} requests, all inside the last ` +
        `${needed.length} of ${groups.length} groups (${needed.reduce((sum, g) => sum + g.end - g.begin, 0)} bytes)`);

  // Both pictures decoded by the browser itself, compared on a canvas: the mean absolute
  // difference per channel over the whole picture, and the share of pixels off by more than 64.
  const compare = (a, b) => page.evaluate(async (a, b) => {
    const load = async (data) => createImageBitmap(await (await fetch(data)).blob());
    const [x, y] = await Promise.all([load(a), load(b)]);
    const pixels = (bitmap) => {
      const canvas = new OffscreenCanvas(bitmap.width, bitmap.height);
      const context = canvas.getContext('2d');
      context.drawImage(bitmap, 0, 0);
      return context.getImageData(0, 0, bitmap.width, bitmap.height).data;
    };
    if (x.width !== y.width || x.height !== y.height) return { error: `${x.width}x${x.height} against ${y.width}x${y.height}` };
    const p = pixels(x), q = pixels(y);
    let sum = 0, far = 0;
    for (let i = 0; i < p.length; i += 4) {
      let worst = 0;
      for (let k = 0; k < 3; ++k) {
        const d = Math.abs(p[i + k] - q[i + k]);
        sum += d;
        worst = Math.max(worst, d);
      }
      if (worst > 64) far += 1;
    }
    return { mean: sum / (3 * p.length / 4), far: far / (p.length / 4) };
  }, `data:image/png;base64,${readFileSync(a).toString('base64')}`, `data:image/png;base64,${readFileSync(b).toString('base64')}`);
  const shots = [];

  // Screenshots against fmdec --preview at three times.
  const times = [info.firstTime + 0.25 * info.duration, info.firstTime + 0.5 * info.duration, info.firstTime + 0.8 * info.duration];
  for (const t of times) {
    await page.evaluate((time) => window.facemorphPage.seek(time), t);
    const shot = join(out, `browser_${t.toFixed(3)}.png`);
    // The canvas's own pixels (not a screenshot of the page, which may resize it).
    const png = await page.evaluate(() => window.facemorphPage.snapshot());
    writeFileSync(shot, Buffer.from(png.slice(png.indexOf(',') + 1), 'base64'));
    const native = join(out, `native_${t.toFixed(3)}.png`);
    execFileSync(fmdec, [file, '--t', String(t), '--preview', native, '--preview-size', '800', '--quiet'], { stdio: 'inherit' });
    const difference = await compare(shot, native);
    if (difference.error) check(false, `t = ${t.toFixed(3)} s: ${difference.error}`);
    else check(difference.mean <= tolerance && difference.far <= 0.03,
               `t = ${t.toFixed(3)} s: the canvas against fmdec --preview: mean difference ${difference.mean.toFixed(2)} per channel (≤ ${tolerance}), ` +
               `${(100 * difference.far).toFixed(2)}% of pixels off by more than 64 (≤ 3%)`);
    shots.push({ t, shot, native });
  }
  const control = await compare(shots[0].shot, shots[shots.length - 1].native);
  check(control.mean > tolerance, `control: the canvas at t = ${shots[0].t.toFixed(3)} s against the preview of t = ${shots[shots.length - 1].t.toFixed(3)} s ` +
        `differs by ${control.mean.toFixed(2)} per channel, more than the tolerance`);

  // Decode time per frame inside the browser: the worker's fm_decoder_decode, 60 frames over the range.
  const timeDecoding = async (fileUrl2) => page.evaluate(async (u) => {
    const fp = window.facemorphPage;
    const i = await fp.open(u);
    const times = [];
    for (let k = 0; k < 60; ++k) {
      const frame = await fp.seek(i.firstTime + (i.duration * k) / 59);
      times.push(frame.decodeMs);
    }
    times.sort((a, b) => a - b);
    return { n: i.gridN, mean: times.reduce((a, b) => a + b, 0) / times.length, median: times[30], worst: times[times.length - 1] };
  }, fileUrl2);
  for (const f of [file, ...speedFiles.map((s) => resolve(s))]) {
    const r = await timeDecoding('/' + relative(root, f));
    console.log(`decode in the browser: ${relative(root, f)}: N = ${r.n}: mean ${r.mean.toFixed(2)} ms, median ${r.median.toFixed(2)} ms, ` +
                `worst ${r.worst.toFixed(2)} ms a frame (60 frames; ${(1000 / r.mean).toFixed(0)} fps of decoding)`);
  }
  check(consoleErrors.length === 0, `no console errors${consoleErrors.length ? ': ' + consoleErrors.join(' | ') : ''}`);
} finally {
  await browser.close();
  server.close();
}
writeFileSync(join(out, 'server-log.json'), JSON.stringify(log, null, 1));
process.exit(failures.length ? 1 : 0);
