// After `vite build`: a gzip copy of each text asset, which the server sends to browsers that
// accept it (opencv.js in the worker is 15 MB as built, 4 MB gzipped: the first load on a phone).
import { readdirSync, readFileSync, statSync, writeFileSync } from 'node:fs';
import { join } from 'node:path';
import { gzipSync } from 'node:zlib';

function* files(dir) {
  for (const name of readdirSync(dir)) {
    const p = join(dir, name);
    if (statSync(p).isDirectory()) yield* files(p);
    else yield p;
  }
}

for (const p of files(new URL('./dist', import.meta.url).pathname)) {
  if (!/\.(js|css|html|svg|webmanifest)$/.test(p) || statSync(p).size < 1024) continue;
  writeFileSync(`${p}.gz`, gzipSync(readFileSync(p), { level: 9 }));
}
