// Browser test of `raisov serve`: start the server on a free port, load the page in Debian's
// Chromium (headless, software WebGL), Shift-drag on the organ, check that the surface moved
// and the grasp force readout is non-zero, save a screenshot; then check that a page of
// another site, open in the same browser, cannot open the viewer's WebSocket. A second test
// cuts the organ with the scalpel (c, then a drag across it): the server sends the cut body's
// topology, with more vertices, and a grasp then pulls a lip of the wound.
// Env: RAISOV_BIN (default target/release/raisov), CHROMIUM (default /usr/bin/chromium),
// SCREENSHOT (default target/browser/serve.png).
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { spawn } from 'node:child_process';
import { createServer } from 'node:http';
import { mkdirSync } from 'node:fs';
import { dirname, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';
import { chromium } from 'playwright-core';

const root = resolve(dirname(fileURLToPath(import.meta.url)), '..', '..');
const bin = process.env.RAISOV_BIN ?? resolve(root, 'target/release/raisov');
const shot = process.env.SCREENSHOT ?? resolve(root, 'target/browser/serve.png');

const browserArgs = ['--headless', '--no-sandbox', '--disable-background-networking', '--disable-component-update',
  '--disable-sync', '--no-first-run', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'];

function startServer() {
  return new Promise((ok, fail) => {
    const p = spawn(bin, ['serve', '--port', '0'], { cwd: root, stdio: ['ignore', 'pipe', 'pipe'] });
    let out = '';
    const timer = setTimeout(() => fail(new Error(`no URL from raisov serve in 60 s:\n${out}`)), 60000);
    const onData = (d) => {
      out += d.toString();
      const m = out.match(/open (http:\/\/\S+)/);
      if (m) { clearTimeout(timer); ok({ proc: p, url: m[1] }); }
    };
    p.stdout.on('data', onData);
    p.stderr.on('data', onData);
    p.on('exit', (c) => { clearTimeout(timer); fail(new Error(`raisov serve exited (${c}):\n${out}`)); });
  });
}

test('raisov serve: Shift-drag grasps the organ in the browser', { timeout: 110000 }, async () => {
  const { proc, url } = await startServer();
  const browser = await chromium.launch({
    executablePath: process.env.CHROMIUM ?? '/usr/bin/chromium',
    args: browserArgs,
  });
  try {
    const page = await browser.newPage({ viewport: { width: 1100, height: 750 } });
    const errors = [];
    page.on('pageerror', (e) => errors.push(String(e)));
    // A WebGL context first: without it there is nothing to test.
    await page.goto('about:blank');
    const gl = await page.evaluate(() => !!document.createElement('canvas').getContext('webgl2'));
    assert.ok(gl, 'no WebGL context in this Chromium (swiftshader flags?)');
    await page.goto(url);
    await page.waitForFunction(() => window.raisovState && window.raisovState.frames > 3
      && window.raisovState.client !== null, null, { timeout: 30000 });
    const s0 = await page.evaluate(() => ({ webgl: window.raisovState.webgl, n: window.raisovState.topology.n }));
    assert.ok(s0.webgl, 'the page has no WebGL context');
    assert.ok(s0.n > 100, `surface of ${s0.n} vertices`);
    // Shift-drag from the organ's middle (the camera looks at its bounding-box centre) downwards.
    const vp = page.viewportSize();
    const [x0, y0] = [vp.width / 2, vp.height / 2];
    await page.keyboard.down('Shift');
    await page.mouse.move(x0, y0);
    await page.mouse.down();
    for (let k = 1; k <= 20; k++) {
      await page.mouse.move(x0 + 1.5 * k, y0 + 4 * k);
      await page.waitForTimeout(50);
    }
    await page.waitForFunction(() => window.raisovState.holder === window.raisovState.client
      && window.raisovState.forceN > 0, null, { timeout: 20000 });
    await page.waitForTimeout(2500);
    const r = await page.evaluate(() => {
      const s = window.raisovState;
      let moved = 0;
      for (let i = 0; i < s.positions.length; i += 3) {
        const d = Math.hypot(s.positions[i] - s.firstPositions[i], s.positions[i + 1] - s.firstPositions[i + 1],
          s.positions[i + 2] - s.firstPositions[i + 2]);
        moved = Math.max(moved, d);
      }
      return { moved, forceN: s.forceN, text: document.getElementById('force').textContent,
        bytes: s.bytesPerFrame, latency: s.latencyMs, simFps: s.simFps, errors: s.errors,
        samples: s.latencySamples.slice(), method: s.frameMethod };
    });
    mkdirSync(dirname(shot), { recursive: true });
    await page.screenshot({ path: shot });
    await page.mouse.up();
    await page.keyboard.up('Shift');

    // A pin (Ctrl+click) is drawn and counted.
    await page.keyboard.down('Control');
    await page.mouse.click(x0 - 30, y0 - 60);
    await page.keyboard.up('Control');
    await page.waitForFunction(() => window.raisovState.pins.length === 1, null, { timeout: 10000 });

    // The colour switch and back: the displacement legend is in metres again (this organ
    // moves centimetres), not the stress legend's pascals read as metres.
    const framesNow = () => page.evaluate(() => window.raisovState.frames);
    await page.click('input[name=colour][value="1"]');
    await page.waitForFunction(() => window.raisovState.legendStress === true, null, { timeout: 10000 });
    const stressMax = await page.evaluate(() => window.raisovState.legendMax);
    await page.click('input[name=colour][value="0"]');
    await page.waitForFunction(() => window.raisovState.legendStress === false, null, { timeout: 10000 });
    const uMax = await page.evaluate(() => window.raisovState.legendMax);
    console.log(`legend: stress max ${stressMax.toPrecision(3)} Pa, then displacement max ${(uMax * 1e3).toPrecision(3)} mm`);
    assert.ok(uMax < 0.1, `the displacement legend reads ${uMax} m after the colour switch`);

    // Every method: after the switch either frames of that method with work in them arrive, or
    // the page says that the method diverged. Never a silent, frozen panel.
    const outcomes = [];
    for (const code of [0, 1, 2, 3]) {
      const before = await framesNow();
      await page.click(`input[name=method][value="${code}"]`);
      await page.waitForFunction((c) => window.raisovState.method === c, code, { timeout: 60000 });
      // Wake the simulation (at rest it sleeps) with a short grasp and release.
      await page.keyboard.down('Shift');
      await page.mouse.move(x0, y0);
      await page.mouse.down();
      await page.mouse.move(x0 + 3, y0 + 8);
      await page.waitForTimeout(300);
      await page.mouse.up();
      await page.keyboard.up('Shift');
      await page.waitForFunction(({ c, n0 }) => {
        const s = window.raisovState;
        const stepped = s.frames > n0 + 3 && s.frameMethod === c && s.cycles > 0;
        const told = s.diverged && s.errors.some((e) => e.includes('diverged'));
        return stepped || told;
      }, { c: code, n0: before }, { timeout: 30000 });
      const o = await page.evaluate(() => ({ method: window.raisovState.method, diverged: window.raisovState.diverged,
        status: document.getElementById('status').textContent, budget: document.getElementById('budget').textContent }));
      outcomes.push(o);
    }
    console.log(`methods: ${JSON.stringify(outcomes)}`);
    await page.screenshot({ path: shot.replace(/\.png$/, '-end.png') });
    console.log(`surface moved ${(r.moved * 1e3).toFixed(2)} mm, grasp force ${r.text}, ` +
      `${r.bytes} bytes/frame, sim ${r.simFps.toFixed(1)} fps, grasp→frame ${r.latency?.toFixed(1)} ms; ${shot}`);
    // Latency of the drag's grasp moves: from the page sending a move to the first frame that
    // applied it (end to end), and the server's part, from the message's arrival to the end of
    // that frame, in frame periods. Recorded as figures (the goal is 2 frame periods on the
    // server, 50 ms end to end); the assertions are bounds a loaded CI machine keeps: the
    // server's part in frame periods, and end to end only a stall (5 s). End to end is mostly
    // the headless browser's drawing: inside a whole CI run the median was 133-329 ms on one
    // 2-core host, 445-603 ms on a slower one and once 2 094 ms there (the server's part 1.92
    // periods in that run as in the others; the same build alone right after: 344 ms), and
    // frames sent faster than the browser draws them queued to 1.8-2 s (bench/RESULTS.md).
    const med = (a) => { const b = [...a].sort((x, y) => x - y); return b.length ? b[Math.floor(b.length / 2)] : NaN; };
    const e2e = r.samples.map((x) => x.e2e);
    const periods = r.samples.filter((x) => x.period).map((x) => x.server / x.period);
    console.log(`grasp latency (method ${r.method}, ${r.samples.length} moves): end to end median ` +
      `${med(e2e).toFixed(1)} ms, largest ${Math.max(...e2e).toFixed(1)} ms; on the server median ` +
      `${med(r.samples.map((x) => x.server)).toFixed(1)} ms = ${med(periods).toFixed(2)} frame periods, ` +
      `largest ${Math.max(...periods).toFixed(2)}; frame ${med(r.samples.map((x) => x.frameMs)).toFixed(1)} ms`);
    assert.ok(r.samples.length >= 5, `${r.samples.length} grasp moves measured`);
    assert.ok(med(e2e) < 5000, `median grasp-to-frame latency ${med(e2e)} ms (a stall)`);
    assert.ok(med(periods) <= 5, `median server latency ${med(periods)} frame periods`);
    assert.ok(r.moved > 1e-3, `surface vertices moved ${r.moved} m (want > 1 mm)`);
    assert.ok(r.forceN > 0 && parseFloat(r.text) > 0, `force readout ${r.text}`);
    assert.deepEqual(errors, [], 'page errors');

    // A page of another origin (another port of this machine) tries the viewer's WebSocket:
    // the browser sends that page's Origin and the server refuses the upgrade.
    const other = createServer((_, res) => { res.writeHead(200, { 'content-type': 'text/html' }); res.end('<p>another site</p>'); });
    await new Promise((ok) => other.listen(0, '127.0.0.1', ok));
    try {
      const evil = await browser.newPage();
      await evil.goto(`http://127.0.0.1:${other.address().port}/`);
      const wsUrl = url.replace(/^http/, 'ws').replace(/\/(\?.*)?$/, '/ws');
      const outcome = await evil.evaluate((u) => new Promise((ok) => {
        const ws = new WebSocket(u);
        ws.onopen = () => ok('open');
        ws.onerror = () => ok('refused');
        setTimeout(() => ok('timeout'), 10000);
      }), wsUrl);
      console.log(`a WebSocket from another origin to ${wsUrl}: ${outcome}`);
      assert.equal(outcome, 'refused', 'a cross-origin page opened the WebSocket');
    } finally {
      other.close();
    }
  } finally {
    await browser.close();
    proc.kill();
  }
});

test('raisov serve: the scalpel cuts the organ and a grasp pulls the wound', { timeout: 150000 }, async () => {
  const { proc, url } = await startServer();
  const browser = await chromium.launch({ executablePath: process.env.CHROMIUM ?? '/usr/bin/chromium', args: browserArgs });
  try {
    const page = await browser.newPage({ viewport: { width: 1100, height: 750 } });
    const errors = [];
    page.on('pageerror', (e) => errors.push(String(e)));
    await page.goto(url);
    await page.waitForFunction(() => window.raisovState && window.raisovState.frames > 3
      && window.raisovState.client !== null, null, { timeout: 30000 });
    const before = await page.evaluate(() => ({ n: window.raisovState.topology.n, m: window.raisovState.topology.m,
      topologies: window.raisovState.topologies }));
    assert.equal(before.topologies, 1);
    // Scalpel mode (the c key), then a drag across the organ's middle, left to right.
    await page.keyboard.press('c');
    assert.ok(await page.evaluate(() => window.raisovState.scalpel), 'c did not enter scalpel mode');
    const vp = page.viewportSize();
    const [x0, y0] = [vp.width / 2, vp.height / 2];
    await page.mouse.move(x0 - 60, y0);
    await page.mouse.down();
    for (let k = 1; k <= 12; k++) {
      await page.mouse.move(x0 - 60 + 10 * k, y0);
      await page.waitForTimeout(80);
    }
    await page.mouse.up();
    // The server answers the cuts and sends the cut body's surface: a second topology (or more)
    // with more vertices (the wound's faces).
    await page.waitForFunction((n0) => {
      const s = window.raisovState;
      // Every cut answered, and the topology of the last one arrived (the reply names its counts).
      return s.cutsSent > 0 && s.cutsAnswered === s.cutsSent && s.topologies >= 2 && s.topology.n > n0
        && s.cuts > 0 && s.lastCut && s.topology.n === s.lastCut.vertices && s.firstPositions !== null;
    }, before.n, { timeout: 90000 });
    const cut = await page.evaluate(() => {
      const s = window.raisovState;
      return { n: s.topology.n, m: s.topology.m, topologies: s.topologies, sent: s.cutsSent, cuts: s.cuts,
        last: s.lastCut, errors: s.errors };
    });
    console.log(`scalpel: ${cut.sent} cut message(s) sent, ${cut.cuts} split the liver; surface ${before.n} -> ${cut.n} ` +
      `vertices, ${before.m} -> ${cut.m} triangles; last cut ${JSON.stringify(cut.last)}; errors ${JSON.stringify(cut.errors)}`);
    assert.ok(cut.n > before.n && cut.m > before.m, `the cut surface has ${cut.n} vertices, ${cut.m} triangles`);
    // Leave scalpel mode; Shift-drag the lip above the cut upwards: the grasp works on the cut body.
    await page.keyboard.press('c');
    await page.keyboard.down('Shift');
    await page.mouse.move(x0, y0 - 12);
    await page.mouse.down();
    for (let k = 1; k <= 15; k++) {
      await page.mouse.move(x0, y0 - 12 - 4 * k);
      await page.waitForTimeout(50);
    }
    await page.waitForFunction(() => window.raisovState.holder === window.raisovState.client
      && window.raisovState.forceN > 0, null, { timeout: 30000 });
    await page.waitForTimeout(2500);
    const pulled = await page.evaluate(() => {
      const s = window.raisovState;
      let moved = 0;
      for (let i = 0; i < s.positions.length; i += 3) {
        moved = Math.max(moved, Math.hypot(s.positions[i] - s.firstPositions[i],
          s.positions[i + 1] - s.firstPositions[i + 1], s.positions[i + 2] - s.firstPositions[i + 2]));
      }
      return { moved, forceN: s.forceN, n: s.topology.n };
    });
    const shotCut = shot.replace(/\.png$/, '-scalpel.png');
    mkdirSync(dirname(shotCut), { recursive: true });
    await page.screenshot({ path: shotCut });
    await page.mouse.up();
    await page.keyboard.up('Shift');
    console.log(`pulled the lip: surface moved ${(pulled.moved * 1e3).toFixed(2)} mm, force ${pulled.forceN.toFixed(3)} N; ${shotCut}`);
    assert.equal(pulled.n, cut.n, 'the grasp changed the topology');
    assert.ok(pulled.moved > 1e-3, `surface vertices moved ${pulled.moved} m (want > 1 mm)`);
    assert.ok(pulled.forceN > 0, 'no grasp force on the cut body');
    assert.deepEqual(errors, [], 'page errors');
  } finally {
    await browser.close();
    proc.kill();
  }
});
