// Copies the pinned front-end libraries from node_modules into ../web/vendor (the folder the
// `balloon` binary embeds), or with `--check` verifies that the committed copies are byte for
// byte the files of the packages pinned in package-lock.json (run after `npm ci`).
//
//   node vendor.mjs           copy (after changing a version in package.json + `npm install`)
//   node vendor.mjs --check   exit 1 naming every vendored file that differs or is missing

import { readFileSync, writeFileSync, mkdirSync, existsSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const vendorDir = join(here, '..', 'web', 'vendor');

// [file in node_modules, file under web/vendor]. three.module.js imports ./three.core.js, and
// OrbitControls imports the bare name "three" (resolved by the page's import map).
export const FILES = [
  ['three/build/three.module.js', 'three.module.js'],
  ['three/build/three.core.js', 'three.core.js'],
  ['three/examples/jsm/controls/OrbitControls.js', 'OrbitControls.js'],
  ['three/LICENSE', 'LICENSE-three.txt'],
];

function pinnedVersion(pkg) {
  const lock = JSON.parse(readFileSync(join(here, 'package-lock.json'), 'utf8'));
  const entry = lock.packages?.[`node_modules/${pkg}`];
  if (!entry) throw new Error(`package-lock.json: no entry for ${pkg}`);
  return entry.version;
}

function installedVersion(pkg) {
  const file = join(here, 'node_modules', pkg, 'package.json');
  if (!existsSync(file)) {
    throw new Error(`${file} is missing: run \`npm ci\` in ${here} first`);
  }
  return JSON.parse(readFileSync(file, 'utf8')).version;
}

function main() {
  const check = process.argv.includes('--check');
  const pinned = pinnedVersion('three');
  const installed = installedVersion('three');
  if (pinned !== installed) {
    throw new Error(
      `node_modules has three ${installed} but package-lock.json pins ${pinned}: run \`npm ci\``,
    );
  }
  const bad = [];
  mkdirSync(vendorDir, { recursive: true });
  for (const [src, dst] of FILES) {
    const from = readFileSync(join(here, 'node_modules', src));
    const to = join(vendorDir, dst);
    if (check) {
      if (!existsSync(to)) bad.push(`${dst}: missing (expected a copy of ${src})`);
      else if (!readFileSync(to).equals(from)) bad.push(`${dst}: differs from ${src}`);
    } else {
      writeFileSync(to, from);
      console.log(`vendored ${src} -> web/vendor/${dst} (${from.length} bytes)`);
    }
  }
  if (bad.length) {
    throw new Error(
      `web/vendor does not match three ${pinned} from package-lock.json:\n  ${bad.join('\n  ')}\n` +
        'run `node vendor.mjs` in crates/balloon-viewer/frontend and commit web/vendor',
    );
  }
  if (check) console.log(`web/vendor matches three ${pinned} byte for byte (${FILES.length} files)`);
}

try {
  main();
} catch (e) {
  console.error(`vendor.mjs: ${e.message}`);
  process.exit(1);
}
