// Bundles the dashboard: src/main.js (+ three) -> OUT/assets/app.js, copies index.html and style.css.
// Usage: node build.mjs --out DIR [--modules DIR/node_modules]
// Writes into OUT.partial and renames at the end, so a failed build never leaves a half dashboard.
import { createRequire } from 'node:module';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const here = path.dirname(fileURLToPath(import.meta.url));

function parseArgs(argv) {
  const args = { out: null, modules: path.join(here, 'node_modules') };
  for (let i = 0; i < argv.length; i++) {
    const a = argv[i];
    if (a === '--out') args.out = argv[++i];
    else if (a === '--modules') args.modules = argv[++i];
    else if (a === '--help') { console.log('usage: node build.mjs --out DIR [--modules NODE_MODULES_DIR]'); process.exit(0); }
    else { console.error(`build.mjs: unknown argument '${a}'`); process.exit(2); }
  }
  if (!args.out) { console.error('build.mjs: --out DIR is required'); process.exit(2); }
  return args;
}

const args = parseArgs(process.argv.slice(2));
const modules = path.resolve(args.modules);
const requireFromModules = createRequire(path.join(modules, 'noop.js'));
let esbuild;
try {
  esbuild = requireFromModules('esbuild');
} catch (e) {
  console.error(`build.mjs: esbuild not found under ${modules} (run npm ci first)`);
  process.exit(1);
}

const out = path.resolve(args.out);
const assets = path.join(out, 'assets');
const staging = path.join(path.dirname(out), `.${path.basename(out)}-assets.partial`);
fs.rmSync(staging, { recursive: true, force: true });
fs.mkdirSync(staging, { recursive: true });

try {
  await esbuild.build({
    entryPoints: [path.join(here, 'src', 'main.js')],
    bundle: true,
    format: 'esm',
    target: ['chrome100', 'firefox100', 'safari15'],
    minify: true,
    sourcemap: true,
    legalComments: 'linked',
    outfile: path.join(staging, 'app.js'),
    nodePaths: [modules],
    logLevel: 'warning',
  });
  fs.copyFileSync(path.join(here, 'src', 'style.css'), path.join(staging, 'style.css'));
} catch (e) {
  fs.rmSync(staging, { recursive: true, force: true });
  console.error(`build.mjs: bundling failed: ${e.message.split('\n')[0]}`);
  process.exit(1);
}

// Only our own files are replaced: OUT also holds CMake's bookkeeping for this folder.
fs.mkdirSync(out, { recursive: true });
fs.rmSync(assets, { recursive: true, force: true });
fs.renameSync(staging, assets);
const indexTmp = path.join(out, '.index.html.partial');
fs.copyFileSync(path.join(here, 'src', 'index.html'), indexTmp);
fs.renameSync(indexTmp, path.join(out, 'index.html'));
const size = fs.statSync(path.join(assets, 'app.js')).size;
console.log(`dashboard: ${path.join(out, 'index.html')} + assets/app.js (${(size / 1024).toFixed(0)} KiB)`);
