// End-to-end test of `balloon view`, driven the way a person uses it: start the real server,
// open the page in headless Chromium, watch the frame counter advance, drag the body with the
// mouse and check in the server's own state (GET /api/state) that the body moved, pause and
// resume, type an invalid control value and expect a visible error, and save a screenshot per
// system to target/e2e/viewer-<system>.png. Run by `cargo xtask e2e` (which builds the binary).
// A scenario run (a scenario file given in --systems, relative to the workspace, and the
// built-in `connect`) is dragged like the built-in systems (the drag acts on top of the
// scenario's anchors and loads), and a value changed on the page must be in the scenario the
// "save scenario" link downloads, which `balloon run` must accept.
//
//   node e2e.mjs [--balloon PATH] [--systems shell,volumetric,two-layer,connect,FILE.toml]
//                [--out DIR] [--chromium PATH] [--mock]
//
// --mock runs the page against mock-server.mjs instead of the binary (page development only).
// Prints one line per system and closes with "N passed, M failed"; exits 1 on any failure.

import { chromium } from 'playwright-core';
import { spawn, spawnSync } from 'node:child_process';
import { mkdirSync, readFileSync, rmSync } from 'node:fs';
import { basename, dirname, extname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const root = resolve(here, '..', '..', '..');
const opt = (name, dflt) => {
  const i = process.argv.indexOf(`--${name}`);
  return i > 0 && process.argv[i + 1] ? process.argv[i + 1] : dflt;
};
const mock = process.argv.includes('--mock');
const balloon = resolve(opt('balloon', join(root, 'target', 'debug', 'balloon')));
const systems = opt('systems', 'shell,volumetric,two-layer,connect,examples/pinned-neck/pinned-neck.toml,examples/drop-sphere/drop-sphere.toml,examples/static-sphere/static-sphere.toml')
  .split(',').filter(Boolean);
/** A --systems entry that is a scenario file (a path ending in .toml or .json). */
const isFile = (system) => /\.(toml|json)$/i.test(system);
/** The name of an entry in file names and lines: a scenario file's base name. */
const label = (system) => (isFile(system) ? basename(system, extname(system)) : system);
const outDir = resolve(opt('out', join(root, 'target', 'e2e')));
const chromiumPath = opt('chromium', '/usr/bin/chromium');
// Software WebGL: headless without a GPU (SwiftShader through ANGLE).
const CHROMIUM_ARGS = ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
  '--disable-background-networking', '--disable-component-update', '--disable-sync',
  '--use-angle=swiftshader', '--enable-unsafe-swiftshader'];

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
const sub = (a, b) => a.map((x, i) => x - b[i]);
const dot = (a, b) => a.reduce((s, x, i) => s + x * b[i], 0);
const norm = (a) => Math.sqrt(dot(a, a));
const mm = (m) => `${(m * 1000).toFixed(2)} mm`;

// The server applies a message between two steps, so a drag, a pinch or a release reaches its
// state only after the step in progress: a step of a scenario run with converged Newton on a
// 2562-vertex icosphere (static-sphere, both balloons of `connect`) took several seconds right
// after a drag in a debug build at load average 10, and `connect` waited more than 30 s for a
// pinch on 2 busy cores. So a wait for a message's effect (`untilApplied`) is not a fixed time:
// it lasts while the server keeps stepping, and fails when the server took
// APPLIED_WITHIN_STEPS steps (and at least APPLIED_WITHIN_MS) without showing the effect (the
// message was lost), when no step ended for STEP_WAIT (the server is stuck), or after
// APPLY_CAP in all.
const STEP_WAIT = 120000;
const APPLIED_WITHIN_STEPS = 3;
const APPLIED_WITHIN_MS = 5000;
const APPLY_CAP = 300000;
// What the page shows after a step (a new frame, the legend of a new colour field) and motion
// over several steps: a time limit, generous for the same reason.
const FRAME_WAIT = 60000;

class Failure extends Error {}
function check(cond, what) {
  if (!cond) throw new Failure(what);
}

/** Polls `fn` until it returns a truthy value; fails naming `what` after `ms`. */
async function until(what, fn, ms = 15000, every = 100) {
  const end = Date.now() + ms;
  for (;;) {
    const v = await fn();
    if (v) return v;
    if (Date.now() > end) throw new Failure(`timed out after ${ms / 1000} s waiting for ${what}`);
    await sleep(every);
  }
}

/** Polls the server's state until `fn(state)` is truthy: the effect of a message the server
 *  applies between two steps (see STEP_WAIT); fails naming `what` and why. */
async function untilApplied(url, what, fn) {
  const t0 = Date.now();
  const s0 = await state(url);
  if (fn(s0)) return s0;
  const first = s0.step;
  let last = first;
  let lastChange = t0;
  for (;;) {
    await sleep(100);
    const s = await state(url);
    if (fn(s)) return s;
    // A failed step stops the run: say so instead of waiting for a step that never comes.
    check(!s.last_error, `the simulation failed while waiting for ${what}: ${s.last_error}`);
    const now = Date.now();
    if (s.step !== last) {
      last = s.step;
      lastChange = now;
    }
    const steps = last - first;
    if (steps >= APPLIED_WITHIN_STEPS && now - t0 > APPLIED_WITHIN_MS) {
      throw new Failure(`${what}: not seen after ${steps} steps of the server (${((now - t0) / 1000).toFixed(1)} s)`);
    }
    if (now - lastChange > STEP_WAIT) {
      throw new Failure(`timed out waiting for ${what}: the server ended no step for ${STEP_WAIT / 1000} s (at step ${last})`);
    }
    if (now - t0 > APPLY_CAP) throw new Failure(`timed out after ${APPLY_CAP / 1000} s waiting for ${what}`);
  }
}

const servers = new Set();
function killAll() {
  for (const s of servers) s.kill('SIGKILL');
}
process.on('exit', killAll);
for (const sig of ['SIGINT', 'SIGTERM']) process.on(sig, () => { killAll(); process.exit(130); });

/** Starts the server and resolves with { child, url } once it printed its URL line. */
function startServer(system) {
  const cmd = mock ? process.execPath : balloon;
  // --exit-after: a server the test fails to kill still goes away by itself.
  const args = mock ? [join(here, 'mock-server.mjs'), system]
    : ['view', isFile(system) ? resolve(root, system) : system, '--no-open', '--port', '0', '--exit-after', '120'];
  const child = spawn(cmd, args, { stdio: ['ignore', 'pipe', 'pipe'] });
  servers.add(child);
  child.on('exit', () => servers.delete(child));
  let out = '';
  let err = '';
  child.stderr.on('data', (d) => { err += d; });
  return new Promise((res, rej) => {
    const timer = setTimeout(() => rej(new Failure(`${cmd} ${args.join(' ')} printed no URL within 30 s; stderr:\n${err}`)), 30000);
    child.on('error', (e) => { clearTimeout(timer); rej(new Failure(`cannot start ${cmd}: ${e.message}`)); });
    child.on('exit', (code) => { clearTimeout(timer); rej(new Failure(`${cmd} ${args.join(' ')} exited (${code}) before serving; stderr:\n${err}`)); });
    child.stdout.on('data', (d) => {
      out += d;
      const m = out.match(/^balloon view: serving (\S+) at (http:\/\/\S+)$/m);
      if (m) {
        clearTimeout(timer);
        res({ child, url: m[2], stderr: () => err });
      }
    });
  });
}

async function state(url, vertex) {
  const res = await fetch(new URL(vertex === undefined ? 'api/state' : `api/state?vertex=${vertex}`, url));
  check(res.ok, `GET /api/state answered ${res.status}`);
  return res.json();
}

const frameOf = async (page) => Number(await page.textContent('#frame'));

/** Moves the mouse over points near the canvas centre until the page shows the "over the body"
 *  cursor (its own raycast); returns that point. */
async function pointOverBody(page, box) {
  const cx = box.x + box.width / 2;
  const cy = box.y + box.height / 2;
  for (const [dx, dy] of [[0, 0], [0.1, 0], [-0.1, 0], [0, 0.1], [0, -0.1], [0.2, 0.1], [-0.2, -0.1]]) {
    const p = [cx + dx * box.width, cy + dy * box.height];
    await page.mouse.move(p[0], p[1]);
    const over = await page.waitForFunction(() => document.getElementById('canvas').classList.contains('over-body'),
      null, { timeout: 1000 }).then(() => true, () => false);
    if (over) return p;
  }
  throw new Failure('no point of the canvas near its centre is over the body');
}

/** One system: everything a person would try. Returns a one-line summary. */
async function testSystem(browser, system) {
  const name = label(system);
  for (const f of [`viewer-${name}.png`, `viewer-${name}-failed.png`]) rmSync(join(outDir, f), { force: true });
  const { child, url, stderr } = await startServer(system);
  const context = await browser.newContext({ viewport: { width: 1200, height: 760 }, acceptDownloads: true });
  const page = await context.newPage();
  const problems = [];
  page.on('console', (m) => { if (m.type() === 'error') problems.push(`console error: ${m.text()}`); });
  page.on('pageerror', (e) => problems.push(`page error: ${e.message}`));
  page.on('requestfailed', (r) => problems.push(`request failed: ${r.url()} (${r.failure()?.errorText})`));
  const notes = [];
  try {
    // 1. The page loads and the frame counter advances.
    await page.goto(url);
    await until('the first frame (#frame shows a number)', async () => Number.isFinite(await frameOf(page)));
    const f0 = await frameOf(page);
    const f1 = await until('#frame to advance', async () => { const f = await frameOf(page); return f > f0 && f; }, FRAME_WAIT);
    notes.push(`frames ${f0}->${f1}`);
    check(await page.isVisible('#legend'), 'the colour legend is not shown');
    // 1b. A static scenario is shown stepping, and the page says so; nothing else has a note.
    const isStatic = isFile(system) && /^\s*static\s*=\s*true\b/m.test(readFileSync(resolve(root, system), 'utf8'));
    const noteShown = !(await page.locator('#note').isHidden());
    check(noteShown === isStatic, `the note is ${noteShown ? 'shown' : 'hidden'} for ${system}`);
    if (isStatic) {
      const note = await page.textContent('#note');
      check(note.includes('static') && note.includes('dynamically'), `the note "${note}" does not say the static solve is shown stepping`);
      notes.push('static: note shown');
    }
    // 1c. The scene's rigid sphere (a volumetric drop-sphere) is drawn where the server has it.
    const sphereNow = (await state(url)).sphere;
    if (sphereNow) {
      const drawn = await until('the page to draw the sphere', async () => page.evaluate(() => window.balloonView.sphere), 5000);
      check(Math.abs(drawn.radius - sphereNow.radius) < 1e-9, `the page draws a sphere of radius ${drawn.radius}, the server has ${sphereNow.radius}`);
      notes.push(`sphere r=${mm(drawn.radius)} drawn`);
    } else {
      check(await page.evaluate(() => window.balloonView.sphere === null), 'a sphere is drawn where the server has none');
    }
    if (/drop-sphere/.test(system)) check(!!sphereNow, `${system} reports no sphere`);

    // 2. Pause stops the simulated time, resume restarts it.
    await page.click('#pause');
    const tp = (await untilApplied(url, 'the server to report paused', (s) => s.paused)).time;
    await sleep(500);
    check((await state(url)).time === tp, 'the simulated time moved while paused');
    await until('#pause to offer "resume"', async () => (await page.textContent('#pause')).trim() === 'resume', 3000);
    await page.click('#pause');
    await untilApplied(url, 'the simulated time to advance after resume', (s) => s.time > tp);
    await until('#pause to offer "pause"', async () => (await page.textContent('#pause')).trim() === 'pause', 3000);

    // 3. Drag the body: find a point of the canvas over the body (the cursor changes there), press,
    //    move up and right, and check in the server's state that the grabbed vertex moved towards
    //    the target. The target is above the grabbed point (world +y is up on the screen), so
    //    gravity (-y) cannot make this pass; inflation moves a vertex facing the camera mostly
    //    along the view direction, which the drag plane is perpendicular to. The body may follow
    //    as a whole (a free body does), so this is not measured relative to the centroid.
    const box = await page.locator('#canvas').boundingBox();
    // Every system and scenario is dragged (a scenario's drag acts on top of its anchors and
    // loads).
    check(!(await page.locator('#drag-row').isHidden()), `${system} offers no drag`);
    // A falling or toppling body (volumetric) can leave the point between the hover test and the
    // press, and a press off the body orbits instead: like a person, release and try again.
    let start;
    let grabbed = null;
    for (let attempt = 1; !grabbed; attempt++) {
      start = await pointOverBody(page, box);
      await page.mouse.down();
      grabbed = await until('the drag to reach the server (/api/state drag)',
        async () => (await state(url)).drag, attempt < 4 ? 3000 : 15000).catch((e) => {
        if (attempt >= 4) throw e;
        return null;
      });
      if (!grabbed) await page.mouse.up();
    }
    const vertex = grabbed.vertex;
    const s0 = await state(url, vertex);
    const p0 = s0.vertex.position;
    const size = norm(sub(s0.bbox_max, s0.bbox_min));
    const pull = Math.min(box.width, box.height) * Number(opt('pull', '0.1'));
    await page.mouse.move(start[0] + pull, start[1] - pull, { steps: 8 });
    const moving = (s) => s.drag && norm(sub(s.drag.target, grabbed.target)) > 1e-6 * size;
    const target = (await untilApplied(url, 'the drag target to move', moving)).drag.target;
    const sDrag = await state(url);
    check(!sDrag.last_error, `the simulation failed during the drag: ${sDrag.last_error}`);
    const want = sub(target, p0);
    check(want[1] > 0, `the drag target ${target} is not above the grabbed point ${p0}`);
    let moved = 0;
    await until(`vertex ${vertex} to move towards the drag target by 2% of the body's size`, async () => {
      const s = await state(url, vertex);
      check(!s.last_error, `the simulation failed during the drag: ${s.last_error}`);
      moved = dot(sub(s.vertex.position, p0), want) / norm(want);
      return moved > 0.02 * size;
    }, FRAME_WAIT, 200);
    notes.push(`drag moved vertex ${vertex} ${mm(moved)} towards the target (body ${mm(size)})`);
    await page.screenshot({ path: join(outDir, `viewer-${name}.png`) });
    await page.mouse.up();
    await untilApplied(url, 'the drag to be released', (s) => s.drag === null);

    // 3b. Where the system offers pinching, the drag-mode select switches the server's mode.
    const modes = await page.$$eval('#drag-mode option', (os) => os.map((o) => o.value));
    if (modes.includes('pinch')) {
      await page.selectOption('#drag-mode', 'pinch');
      const at = await pointOverBody(page, box);
      await page.mouse.down();
      await page.mouse.move(at[0] + 5, at[1] + 5);
      await untilApplied(url, 'a pinch drag on the server', (s) => s.drag?.mode === 'pinch');
      await page.mouse.up();
      await untilApplied(url, 'the pinch to be released', (s) => s.drag === null);
      await page.selectOption('#drag-mode', 'grab');
      const sPinch = await state(url);
      check(!sPinch.last_error, `the simulation failed during the pinch: ${sPinch.last_error}`);
      notes.push('pinch ok');
    }

    // 3c. A pinch held on the stiff StVK sphere crushes its wall (about 30 steps): the server
    //     undoes the drag instead of stopping (docs/viewer.md, "Drags that crush the wall"),
    //     the page shows the notice and ends its drag, and the run goes on.
    if (name === 'static-sphere' && modes.includes('pinch') && !mock) {
      // A drag undone earlier (the pinch of 3b) left its notice: wait for a new one.
      const earlier = (await state(url)).last_notice;
      await page.selectOption('#drag-mode', 'pinch');
      const at = await pointOverBody(page, box);
      await page.mouse.down();
      await page.mouse.move(at[0] + 5, at[1] + 5);
      const undone = await until('a held pinch to be undone (/api/state last_notice)', async () => {
        const s = await state(url);
        check(!s.last_error, `the simulation failed during a held pinch: ${s.last_error}`);
        return s.last_notice && s.last_notice !== earlier && s.drag === null && s;
      }, FRAME_WAIT, 200);
      await page.mouse.up();
      await page.selectOption('#drag-mode', 'grab');
      await until('#notice to show the undone drag', async () => !(await page.locator('#notice').isHidden())
        && (await page.textContent('#notice')).includes('undone'), 10000);
      await until('the run to go on after the undo', async () => (await state(url)).step > undone.step + 2,
        FRAME_WAIT, 200);
      check(!(await state(url)).last_error, 'the simulation failed after the undo');
      notes.push(`held pinch undone (${undone.last_notice.match(/back at step \d+/)?.[0]})`);
    }

    // 4. An invalid control value shows an error naming the control; the server keeps its value.
    const control = await page.evaluate(() => {
      const box = [...document.querySelectorAll('#controls input[type=number]')].find((b) => b.max !== '');
      return box && { id: box.id, name: box.closest('.control').dataset.name, max: Number(box.max) };
    });
    check(control, 'the page shows no bounded number control');
    const bad = control.max * 10 + 1;
    // The server checks the value against the control's range before it is used (no step
    // takes it); a step that failed before would show its own error instead, so say so.
    const sBefore = await state(url);
    check(!sBefore.last_error, `the simulation failed before the invalid value: ${sBefore.last_error}`);
    await page.fill(`#${control.id}`, String(bad));
    await page.press(`#${control.id}`, 'Enter');
    const names = (m) => m.includes(control.name) || m.toLowerCase().includes(control.name.replaceAll('_', ' '));
    await until(`a visible error naming ${control.name} after setting it to ${bad}`, async () => {
      const shown = await page.locator('#error').isVisible();
      return shown && names(await page.textContent('#error'));
    }, 10000).catch(async (e) => {
      const s = await state(url);
      const shown = await page.locator('#error').isVisible() ? await page.textContent('#error') : '(none)';
      throw new Failure(`${e.message}; the page shows "${shown}", server last_error ${JSON.stringify(s.last_error)}`);
    });
    const message = await page.textContent('#error');
    check((await state(url)).controls[control.name] !== bad, `the server accepted ${control.name} = ${bad}`);
    notes.push(`invalid ${control.name}=${bad}: "${message}"`);

    // 4b. A scenario run or a built-in set-up saves its set-up: a value changed on the page is
    //     in the file the "save scenario" link downloads, and `balloon run` accepts that file.
    const saveShown = !(await page.locator('#save').isHidden());
    // Every set-up saves as a scenario (the built-in volumetric body as the `floor` scene).
    check(saveShown, `the save link is hidden for ${system}`);
    if (saveShown && !mock) {
      const dt = (await state(url)).controls.dt;
      check(typeof dt === 'number', 'the scenario run has no dt control');
      // Every digit: the server parses numbers exactly (serde_json's `float_roundtrip`;
      // without it 0.00020248393365432342 arrived as ...344).
      const want = dt / 2;
      await page.fill('#control-dt', String(want));
      await page.press('#control-dt', 'Enter');
      await untilApplied(url, `dt = ${want} on the server`, (s) => s.controls.dt === want);
      const [download] = await Promise.all([page.waitForEvent('download', { timeout: 10000 }), page.click('#save')]);
      const saved = join(outDir, `viewer-${name}-scenario.toml`);
      await download.saveAs(saved);
      const text = readFileSync(saved, 'utf8');
      const dtLine = text.match(/^dt = (\S+)$/m);
      check(dtLine && Number(dtLine[1]) === want, `the saved scenario has no line "dt = ${want}" (${dtLine?.[0]})`);
      if (isFile(system)) {
        const original = readFileSync(resolve(root, system), 'utf8');
        if (/\[\[anchors\]\]/.test(original)) check(/\[\[anchors\]\]/.test(text), 'the saved scenario lost the anchors');
      }
      const run = spawnSync(balloon, ['run', saved, '--steps', '2'], { encoding: 'utf8', timeout: 120000 });
      check(run.status === 0, `balloon run ${saved} --steps 2 failed (${run.status}): ${run.stderr}`);
      notes.push(`saved dt=${want}; balloon run of it ok`);
    }

    // 5. Another colour field: the legend follows the server.
    const fields = await page.$$eval('#scalar option', (os) => os.map((o) => o.value));
    const shown = await page.textContent('#legend-name');
    const field = fields.find((f) => f !== shown) ?? fields[0];
    check(field, 'the colour select offers no scalar field');
    await page.selectOption('#scalar', field);
    await until(`the legend to show ${field}`, async () => (await page.textContent('#legend-name')) === field, FRAME_WAIT);
    notes.push(`colour ${field}`);

    // 6. Reset: the simulated time starts again.
    const before = (await state(url)).time;
    await page.click('#reset');
    await untilApplied(url, 'the simulated time to restart after #reset', (s) => s.time < before);
    await until('#frame to advance after #reset', async () => { const f = await frameOf(page); return f > 0; }, FRAME_WAIT);

    check(problems.length === 0, problems.join('\n'));
    return notes.join('; ');
  } catch (e) {
    await page.screenshot({ path: join(outDir, `viewer-${name}-failed.png`) }).catch(() => {});
    if (problems.length) e.message += `\n${problems.join('\n')}`;
    const last = await state(url).catch(() => null);
    if (last) e.message += `\nserver state: frame ${last.frame}, time ${last.time}, paused ${last.paused}, last_error ${JSON.stringify(last.last_error)}`;
    e.message += `\nserver stderr:\n${stderr().slice(-2000)}`;
    throw e;
  } finally {
    await context.close();
    child.kill('SIGTERM');
  }
}

async function main() {
  mkdirSync(outDir, { recursive: true });
  const t0 = Date.now();
  const browser = await chromium.launch({ executablePath: chromiumPath, args: CHROMIUM_ARGS, timeout: 30000 });
  let passed = 0;
  let failed = 0;
  try {
    for (const system of systems) {
      const t = Date.now();
      try {
        const summary = await testSystem(browser, system);
        console.log(`e2e ${label(system)}: ok in ${((Date.now() - t) / 1000).toFixed(1)} s (${summary})`);
        passed += 1;
      } catch (e) {
        console.log(`e2e ${label(system)}: FAILED in ${((Date.now() - t) / 1000).toFixed(1)} s: ${e.message}`);
        failed += 1;
      }
    }
  } finally {
    await browser.close();
    killAll();
  }
  console.log(`e2e: screenshots in ${outDir}; ${((Date.now() - t0) / 1000).toFixed(1)} s in all`);
  console.log(`${passed} passed, ${failed} failed`);
  process.exit(failed ? 1 : 0);
}

main().catch((e) => {
  console.error(`e2e: ${e.message}`);
  killAll();
  process.exit(1);
});
