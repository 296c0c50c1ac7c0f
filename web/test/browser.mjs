// The player page in a real browser (spec/web.md §5): headless Chromium (Debian's) driven by
// puppeteer-core. Serves the repository (web/test/serve.mjs, which logs every range it sends), loads
// web/index.html, opens FILE by URL, and checks:
//   - opening fetched the header, index and chunk framing, not the file (bytes from the server's log);
//   - playing 2 s draws frames; a seek to the end fetches only what the last keyframes need;
//   - the canvas at three times matches fmdec --preview of the same times (mean absolute
//     difference per channel ≤ TOLERANCE, 1.5 by default, and the share of pixels off by more than
//     64 ≤ 3%), while the canvas at the first time against the preview of the last differs by more
//     (the comparison can fail: a control);
//   - a truncated copy of FILE and a PNG, opened on the page, show the error fmdec gives for them
//     ("error (truncated): NAME: ..." with the library's message), leave the view empty (white)
//     and Play and the time slider disabled (issue 48 part 3);
//   - web/examples/minimal.html, as shipped (and as the README shows it), in a second tab of the same browser: it plays FILE
//     (two pictures a second apart differ), the face is inside the frame (drawn pixels, none on the
//     border, spanning a fifth of the picture or more), and it names the PNG's error as fmdec does;
//   - FacemorphThree.fitCamera (under node, no browser) frames a face in metres 5 m from the origin;
//   - nothing was written to the console as an error, and no page error was thrown (but the errors
//     the bad files are meant to raise);
// and reports the decode time per frame inside the browser (the worker's fm_decoder_decode).
//   node web/test/browser.mjs --fmdec FMDEC --file FILE.fmv [--out DIR] [--tolerance 1.5] [--speed FILE2.fmv ...]
// --speed files are only timed: each opened, 60 frames decoded over its range, ms per frame.
// Exits 77 when chromium or puppeteer-core is missing, naming it.
import { execFileSync, spawnSync } from 'node:child_process';
import { existsSync, mkdirSync, readFileSync, statSync, writeFileSync } from 'node:fs';
import { createRequire } from 'node:module';
import { dirname, join, relative, resolve } from 'node:path';
import { fileURLToPath, pathToFileURL } from 'node:url';
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

// A truncated copy of FILE (cut inside its last chunk) and a PNG (a preview), each with what
// fmdec says of it: {name, path, native: {line, status, detail}} ("fmdec: error (STATUS): PATH: DETAIL").
function badFiles(fmv, png) {
  const bytes = readFileSync(fmv);
  const files = [['truncated.fmv', bytes.subarray(0, bytes.length - 100)], ['preview.png', readFileSync(png)]];
  return files.map(([name, content]) => {
    const path = join(out, name);
    writeFileSync(path, content);
    const run = spawnSync(fmdec, [path, '--t', '0', '-o', join(out, 'refused.obj')], { encoding: 'utf8' });
    const line = run.stderr.trim().split('\n').pop();
    const match = /error \(([a-z_]+)\): (.*)$/.exec(line);
    const detail = match && match[2].startsWith(path + ': ') ? match[2].slice(path.length + 2) : null;
    if (run.status === 0 || !detail) throw new Error(`fmdec did not refuse ${path} by name: ${line}`);
    return { name, path, native: { line, status: match[1], detail } };
  });
}

// A PNG's pixels that are not the white background (any channel under 232: antialiasing's faint
// fringe and SwiftShader's dithering aside), their bounding box and the picture's size, decoded by
// the browser of `page`.
const drawnPixels = (page, png) => page.evaluate(async (data) => {
  const bitmap = await createImageBitmap(await (await fetch(data)).blob());
  const canvas = new OffscreenCanvas(bitmap.width, bitmap.height);
  const context = canvas.getContext('2d');
  context.drawImage(bitmap, 0, 0);
  const p = context.getImageData(0, 0, bitmap.width, bitmap.height).data;
  let drawn = 0, x0 = Infinity, y0 = Infinity, x1 = -1, y1 = -1;
  for (let i = 0; i < p.length; i += 4) {
    if (Math.min(p[i], p[i + 1], p[i + 2]) >= 232) continue;
    const x = (i / 4) % bitmap.width, y = Math.floor(i / 4 / bitmap.width);
    drawn += 1;
    x0 = Math.min(x0, x); x1 = Math.max(x1, x); y0 = Math.min(y0, y); y1 = Math.max(y1, y);
  }
  return { drawn, x0, y0, x1, y1, width: bitmap.width, height: bitmap.height };
}, typeof png === 'string' ? png : `data:image/png;base64,${Buffer.from(png).toString('base64')}`);

// web/examples/minimal.html as shipped (?file= only): plays, frames the face, names an error. The
// README's html example is this file, whole (issue 48: the snippet a web developer pastes).
async function minimalPage(browser, fileUrl, png, expectedErrors) {
  const shipped = readFileSync(join(root, 'web/examples/minimal.html'), 'utf8').trimEnd();
  const snippet = /```html\n([\s\S]*?)\n```/.exec(readFileSync(join(root, 'README.md'), 'utf8'));
  check(snippet && snippet[1] === shipped, `the README's html example is web/examples/minimal.html, whole`);
  const tab = await browser.newPage();
  await tab.setViewport({ width: 480, height: 360 });
  const errors = [];
  tab.on('console', (message) => { if (message.type() === 'error') errors.push(message.text()); });
  tab.on('pageerror', (error) => errors.push(String(error)));
  const started = Date.now();
  await tab.goto(`${url}/web/examples/minimal.html?file=${encodeURIComponent(fileUrl)}`, { waitUntil: 'load' });
  const canvas = await tab.waitForSelector('canvas');
  let first = null, firstPng = null;
  for (let i = 0; i < 60 && !(first && first.drawn > 0); ++i) {
    await new Promise((r) => setTimeout(r, 250));
    firstPng = await canvas.screenshot();
    first = await drawnPixels(tab, firstPng);
  }
  const shown = await tab.$eval('#error', (e) => (e.hidden ? null : e.textContent));
  check(first.drawn > 0 && !shown, `minimal.html: a face drawn ${((Date.now() - started) / 1000).toFixed(1)} s after loading${shown ? ': ' + shown : ''}`);
  const inside = first.x0 > 1 && first.y0 > 1 && first.x1 < first.width - 2 && first.y1 < first.height - 2;
  const span = Math.max((first.x1 - first.x0) / first.width, (first.y1 - first.y0) / first.height);
  check(inside && span >= 0.2, `minimal.html: the face is inside the ${first.width}x${first.height} frame: pixels ${first.x0}..${first.x1} x ${first.y0}..${first.y1}, ` +
        `spanning ${(100 * span).toFixed(0)}% of it (at least 20%, none on the border)`);
  await new Promise((r) => setTimeout(r, 1000));
  const later = await canvas.screenshot();
  const moved = await tab.evaluate(async (a, b) => {
    const load = async (data) => { const m = await createImageBitmap(await (await fetch(data)).blob()); const c = new OffscreenCanvas(m.width, m.height); const x = c.getContext('2d'); x.drawImage(m, 0, 0); return x.getImageData(0, 0, m.width, m.height).data; };
    const [p, q] = await Promise.all([load(a), load(b)]);
    let differ = 0;
    for (let i = 0; i < p.length; i += 4) differ += Math.abs(p[i] - q[i]) + Math.abs(p[i + 1] - q[i + 1]) + Math.abs(p[i + 2] - q[i + 2]) > 24;
    return differ;
  }, `data:image/png;base64,${Buffer.from(firstPng).toString('base64')}`, `data:image/png;base64,${Buffer.from(later).toString('base64')}`);
  writeFileSync(join(out, 'minimal.png'), later);
  check(moved > 0, `minimal.html plays: ${moved} pixels changed between two pictures a second apart`);
  check(errors.length === 0, `minimal.html: no console errors${errors.length ? ': ' + errors.join(' | ') : ''}`);
  // A file fmdec refuses: the page names it as fmdec does.
  await tab.goto(`${url}/web/examples/minimal.html?file=/work/${png.name}`, { waitUntil: 'load' });
  const error = await tab.waitForSelector('#error:not([hidden])', { timeout: 30000 }).then((e) => e.evaluate((n) => n.textContent));
  const expected = `error (${png.native.status}): /work/${png.name}: ${png.native.detail}`;
  check(error === expected, `minimal.html on ${png.name}: "${error}", as fmdec says "${png.native.line}"`);
  await tab.close();
}

// FacemorphThree.fitCamera without a browser: a sphere-like face of radius 0.1 m centred 5 m from
// the origin (a capture in metres, off-centre) seen by a default camera at the origin; after the fit
// every vertex projects inside the view and the face spans at least half of it.
async function fitCameraCheck() {
  const THREE = await import(pathToFileURL(join(npmDir, 'node_modules/three/build/three.module.js')).href);
  const { FacemorphThree } = await import(pathToFileURL(join(root, 'web/facemorph.js')).href);
  const positions = [];
  for (let i = 0; i < 200; ++i) {
    const a = 2.4 * i, z = 1 - (i + 0.5) / 100;
    const r = Math.sqrt(1 - z * z);
    positions.push(3 + 0.1 * r * Math.cos(a), 4 + 0.1 * r * Math.sin(a), -0.5 + 0.1 * z);
  }
  const info = { maxVertexCount: 200, maxTriangleCount: 1, textureSize: 0, hasHoles: false };
  const player = { info: () => info };
  for (const camera of [new THREE.PerspectiveCamera(30, 4 / 3), new THREE.OrthographicCamera(-1, 1, 0.75, -0.75)]) {
    const face = new FacemorphThree(THREE, player);
    face.apply({ positions: new Float32Array(positions), normals: new Float32Array(600), uvs: new Float32Array(400),
                 indices: new Uint32Array([0, 1, 2]), vertexCount: 200, triangleCount: 1, textures: [], weights: [] });
    face.fitCamera(camera);
    camera.updateMatrixWorld();
    let lo = Infinity, hi = -Infinity, worst = 0;
    for (let i = 0; i < positions.length; i += 3) {
      const p = new THREE.Vector3(positions[i], positions[i + 1], positions[i + 2]).project(camera);
      worst = Math.max(worst, Math.abs(p.x), Math.abs(p.y), Math.abs(p.z));
      lo = Math.min(lo, p.y); hi = Math.max(hi, p.y);
    }
    check(worst < 1 && hi - lo > 1, `fitCamera (${camera.type}): a 0.1 m face 5 m from the origin projects inside the view (largest |NDC| ${worst.toFixed(2)}), ` +
          `spanning ${(50 * (hi - lo)).toFixed(0)}% of its height`);
  }
}

const failures = [];
const check = (ok, what) => {
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${what}`);
  if (!ok) failures.push(what);
};

// The test's own files (the damaged copies) under /work/, wherever the work folder is.
const { server, url, log } = await serve(root, 0, null, { '/work/': out });
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

  // Files fmdec refuses, opened on the page: the same named error, an empty view, no live controls.
  const bad = badFiles(file, shots[0].native);
  const expectedErrors = [];
  for (const { name, path, native } of bad) {
    const shown = await page.evaluate((u) => window.facemorphPage.open(u).then(() => null, (e) => e.message), `/work/${name}`);
    const expected = `error (${native.status}): /work/${name}: ${native.detail}`;
    expectedErrors.push(expected);
    check(shown === expected, `${name}: the page says "${shown}", as fmdec says "${native.line}"`);
    const controls = await page.evaluate(() => window.facemorphPage.controls());
    check(!controls.play && !controls.time, `${name}: Play and the time slider are disabled after the failed open`);
    const empty = await drawnPixels(page, await page.evaluate(() => window.facemorphPage.snapshot()));
    check(empty.drawn === 0, `${name}: the view is empty after the failed open (${empty.drawn} pixels drawn)`);
  }

  // The example page as shipped, in a second tab of the same browser.
  await minimalPage(browser, fileUrl, bad.find((b) => b.name.endsWith('.png')), expectedErrors);

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
  // The bad files' errors are meant to be logged; anything else is not.
  const unexpected = consoleErrors.filter((text) => !expectedErrors.some((e) => text.includes(e)));
  check(unexpected.length === 0, `no console errors${unexpected.length ? ': ' + unexpected.join(' | ') : ''}`);
} finally {
  await browser.close();
  server.close();
}
await fitCameraCheck();
writeFileSync(join(out, 'server-log.json'), JSON.stringify(log, null, 1));
process.exit(failures.length ? 1 : 0);
