// A static file server for the player page and its tests: GET and HEAD with single byte ranges
// (206 and Content-Range; what facemorph.js streams with), and a log of every response's path,
// range and bytes, so a test can count what playback fetched.
//   node web/test/serve.mjs ROOT [PORT=0] [LOG.jsonl]   prints "listening on http://127.0.0.1:PORT"
// Also importable: serve(root, port, logPath, mounts) -> {server, url, log}; mounts {'/prefix/': folder}
// serve another folder under a path (a test's own files, wherever its work folder is).
import { createServer } from 'node:http';
import { createReadStream, statSync, appendFileSync } from 'node:fs';
import { extname, join, normalize, resolve, sep } from 'node:path';

const types = {
  '.html': 'text/html; charset=utf-8', '.js': 'text/javascript', '.mjs': 'text/javascript', '.css': 'text/css',
  '.wasm': 'application/wasm', '.json': 'application/json', '.png': 'image/png', '.fmv': 'application/octet-stream',
};

export function serve(root, port = 0, logPath = null, mounts = {}) {
  const log = [];
  const server = createServer((request, response) => {
    const path = decodeURIComponent(new URL(request.url, 'http://x').pathname);
    const mount = Object.keys(mounts).find((prefix) => path.startsWith(prefix));
    const base = resolve(mount ? mounts[mount] : root);
    const rest = mount ? path.slice(mount.length - 1) : path;
    const file = normalize(join(base, rest.endsWith('/') ? rest + 'index.html' : rest));
    const record = (status, bytes, range) => {
      const entry = { path, status, bytes, range };
      log.push(entry);
      if (logPath) appendFileSync(logPath, JSON.stringify(entry) + '\n');
    };
    let stat;
    try {
      if (file !== base && !file.startsWith(base + sep)) throw new Error('outside');
      stat = statSync(file);
      if (!stat.isFile()) throw new Error('not a file');
    } catch {
      response.writeHead(404).end();
      record(404, 0, null);
      return;
    }
    const headers = { 'Content-Type': types[extname(file)] || 'application/octet-stream', 'Accept-Ranges': 'bytes', 'Cache-Control': 'no-store' };
    const match = /^bytes=(\d*)-(\d*)$/.exec(request.headers.range || '');
    let begin = 0, end = stat.size - 1, status = 200;
    if (match) {
      if (match[1] === '') { begin = Math.max(0, stat.size - Number(match[2])); } else {
        begin = Number(match[1]);
        if (match[2] !== '') end = Math.min(Number(match[2]), stat.size - 1);
      }
      if (begin >= stat.size || begin > end) {
        response.writeHead(416, { 'Content-Range': `bytes */${stat.size}` }).end();
        record(416, 0, request.headers.range);
        return;
      }
      status = 206;
      headers['Content-Range'] = `bytes ${begin}-${end}/${stat.size}`;
    }
    headers['Content-Length'] = String(end - begin + 1);
    response.writeHead(status, headers);
    record(status, request.method === 'HEAD' ? 0 : end - begin + 1, match ? [begin, end + 1] : null);
    if (request.method === 'HEAD') response.end();
    else createReadStream(file, { start: begin, end }).pipe(response);
  });
  return new Promise((done) => server.listen(port, '127.0.0.1', () => done({ server, url: `http://127.0.0.1:${server.address().port}`, log })));
}

if (import.meta.url === `file://${process.argv[1]}`) {
  const [root = '.', port = '0', logPath = null] = process.argv.slice(2);
  const { url } = await serve(root, Number(port), logPath);
  console.log(`listening on ${url}`);
}
