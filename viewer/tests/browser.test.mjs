// End-to-end test of `tissue view` in headless Chromium (driven by playwright-core; the
// browser is Debian's /usr/bin/chromium). Usage: node browser.test.mjs URL SCREENSHOT.png
// On the probe liver: the page renders with its icon; malformed and oversized messages are
// rejected with an error while the simulation keeps running; a grasp-and-drag moves the
// surface, Reset brings back the scene's dt and the colour scale; the legend shows its
// range; the shortcuts work after the model selector was used; the scalpel's path is drawn
// while dragging; and the switch matrix: every kind the page lists, switched to live,
// holds the probe for 2 s with no blow-up and a bounded force (or is refused with its reason).
import { launch, open, check, info, verdict, switchTo, holdProbe, noticeCount, notices } from './lib.mjs';

/// Presses at screen point `p` and drags up and right in ten moves, then holds 1.5 s (the
/// button stays down: the caller releases it).
async function dragFrom(page, p) {
  await page.mouse.move(p[0], p[1]);
  await page.mouse.down();
  for (let k = 1; k <= 10; k++) {
    await page.mouse.move(p[0] + 6 * k, p[1] - 4 * k);
    await page.waitForTimeout(50);
  }
  await page.waitForTimeout(1500);
}

const [url, shot] = process.argv.slice(2);
// The page lists only the kinds the organ can be built as (`BodyNeed`: spline, which needs
// an open surface, is not offered on the closed liver), so a listed kind that refuses fails
// here. hybrid builds with its automatic region at the organ's top when the scene gives none.
// A kind that may refuse for a reason the list cannot know goes here with the part of its
// message that must appear.
const REFUSED = {};
// The probe pushes one probe radius into the liver: a plausible state gives well under
// this (the issue's exploding spring-mass showed 9.24 N, 10.7 N peak).
const FORCE_BOUND = 3.0;

const browser = await launch();
try {
  const page = await open(browser, url);
  const webgl2 = await page.evaluate(() => !!document.createElement('canvas').getContext('webgl2'));
  check('WebGL 2', webgl2, webgl2 ? 'available' : 'missing');

  const px = await page.evaluate(() => window.__tissue.organPixels());
  const share = px.organ / px.total;
  check('the liver renders', share > 0.005, `${px.organ} of ${px.total} pixels have the tissue colour (${(100 * share).toFixed(2)} %)`);
  await page.screenshot({ path: shot });
  check('no failed request (favicon included)', page.requestsFailed.length === 0, page.requestsFailed.join(', ') || 'none');

  // Robustness: bad messages get an error on the page, the simulation goes on.
  const before = await page.evaluate(() => window.__tissue.last.steps);
  await page.evaluate(() => {
    window.__tissue.sendRaw('{"type":"explode"}');
    window.__tissue.sendRaw('{"type":"probe","position":[1e9,0,0]}');
    window.__tissue.sendRaw(JSON.stringify({ type: 'reset', pad: 'x'.repeat(20000) }));
  });
  await page.waitForFunction(() => window.__tissue.notices.filter((n) => n.level === 'error').length >= 3,
    null, { timeout: 10000 });
  const errors = await page.evaluate(() => window.__tissue.notices.filter((n) => n.level === 'error').map((n) => n.message));
  const banner = await page.evaluate(() => document.getElementById('error-banner').style.display);
  check('malformed messages rejected', errors.some((m) => m.includes('unknown variant')) && errors.some((m) => m.includes('farther than')),
    errors.slice(0, 2).join(' | '));
  check('oversized message rejected', errors.some((m) => m.includes('bytes rejected')), errors[2] || '');
  check('error shown on the page', banner === 'block', `banner display ${banner}`);
  await page.waitForTimeout(500);
  const after = await page.evaluate(() => window.__tissue.last.steps);
  check('simulation keeps running', after > before, `steps ${before} -> ${after}`);

  // The status names the running model and its step.
  const status = await page.evaluate(() => window.__tissue.status);
  const kind0 = await page.evaluate(() => window.__tissue.init.kind);
  check('status shows the model and its step', status.includes(`running ${kind0}`) && /dt \d|static/.test(status), status);

  // Colour map and its legend.
  await page.keyboard.press('c');
  await page.waitForTimeout(300);
  const legend0 = await page.evaluate(() => window.__tissue.legend);
  check('legend shows the range in mm', /^0 mm – \d+(\.\d+)? mm$/.test(legend0), `"${legend0}"`);

  // A scripted grasp and drag, then Reset.
  await page.keyboard.press('2');
  const p = await page.evaluate(() => window.__tissue.organScreenPoint());
  check('organ under the pointer', !!p, JSON.stringify(p));
  if (p) {
    const d0 = await page.evaluate(() => window.__tissue.maxDisplacement || 0);
    await dragFrom(page, p);
    const s = await page.evaluate(() => ({
      disp: window.__tissue.maxDisplacement,
      force: window.__tissue.forceMagnitude,
      shown: document.getElementById('force').textContent,
      size: window.__tissue.init.size,
      legend: window.__tissue.legend,
    }));
    check('drag moves vertices', s.disp > 0.02 * s.size && s.disp > d0,
      `max displacement ${(1000 * s.disp).toFixed(2)} mm (organ size ${(1000 * s.size).toFixed(0)} mm)`);
    const shown = parseFloat(s.shown);
    check('shown force is non-zero', shown > 0 && s.force > 0, `force shown "${s.shown}"`);
    await page.mouse.up();
    const hiDrag = parseFloat(s.legend.split('–')[1]);
    const n0 = await noticeCount(page);
    await page.keyboard.press('r');
    await page.waitForFunction((n) => window.__tissue.notices.slice(n).some((x) => x.message.startsWith('reset')), n0, { timeout: 5000 }).catch(() => {});
    // Two frames drawn after the server's reset (a loaded machine draws few per second).
    const f0 = await page.evaluate(() => window.__tissue.frames);
    await page.waitForFunction((f) => window.__tissue.frames >= f + 2, f0, { timeout: 10000 }).catch(() => {});
    await page.waitForTimeout(300);
    const r = await page.evaluate(() => ({ legend: window.__tissue.legend, status: window.__tissue.status, dt: window.__tissue.last.dt, dt0: window.__tissue.init.dt }));
    const hiReset = parseFloat(r.legend.split('–')[1]);
    check('Reset rescales the colour map', hiReset < 0.5 * hiDrag, `legend top ${hiDrag} mm after the drag, ${hiReset} mm after Reset`);
    check('Reset restores the dt shown', r.dt === r.dt0 && (r.status.includes(`dt ${Number(r.dt0).toExponential(2)}`) || r.status.endsWith('static')),
      `dt ${r.dt} s (the scene's ${r.dt0} s): "${r.status}"`);

    // The strain colours (the model has tetrahedra): the legend in %, grown by a drag.
    await page.selectOption('#quantity', 'strain');
    await dragFrom(page, p);
    const st = await page.evaluate(() => window.__tissue.legend);
    await page.mouse.up();
    const top = parseFloat(st.split('–')[1]);
    check('strain colours: legend in % grown by a drag', /^0 % – \d+(\.\d+)? %$/.test(st) && top > 1, `"${st}"`);
    await page.selectOption('#quantity', 'displacement');
    await page.keyboard.press('r');
    await page.waitForTimeout(600);
  }
  await page.keyboard.press('c');

  // The scalpel: its path is drawn while dragging, with no three.js buffer warning.
  await page.keyboard.press('3');
  const c = await page.evaluate(() => window.__tissue.organScreenPoint());
  if (c) {
    const pathBefore = await page.evaluate(() => window.__tissue.pathPixels());
    await page.mouse.move(c[0] - 40, c[1]);
    await page.mouse.down();
    for (let k = 0; k <= 16; k++) await page.mouse.move(c[0] - 40 + 5 * k, c[1] + 2 * k);
    const pathDrawn = await page.evaluate(() => window.__tissue.pathPixels());
    const n0 = await noticeCount(page);
    await page.mouse.up();
    check('cut path drawn while dragging', pathDrawn > pathBefore + 50, `${pathBefore} -> ${pathDrawn} path-coloured pixels`);
    const buf = page.warnings.filter((w) => w.includes('Buffer size too small'));
    check('no "Buffer size too small" warning', buf.length === 0, `${buf.length} warnings`);
    const kind = await page.evaluate(() => window.__tissue.init.kind);
    await page.waitForFunction((n) => window.__tissue.notices.slice(n).some((x) => x.message.includes('cut')), n0, { timeout: 10000 }).catch(() => {});
    const said = (await notices(page, n0)).map((x) => x.message);
    check('scalpel answered', said.some((m) => m.includes('cannot cut') || m.includes('cut')), `${kind}: ${said.join(' | ')}`);
  }

  // Shortcuts after the model selector was used: pick a kind with the mouse, then keys.
  {
    const kinds = await page.evaluate(() => window.__tissue.init.kinds.map((k) => k.name));
    const target = kinds.includes('tensor-mass') ? 'tensor-mass' : kinds[0];
    await switchTo(page, target);
    const n0 = await noticeCount(page);
    const w0 = await page.evaluate(() => document.getElementById('wire').checked);
    const focus = await page.evaluate(() => document.activeElement && document.activeElement.id);
    await page.keyboard.press('w');
    await page.keyboard.press('c');
    await page.keyboard.press('2');
    await page.waitForTimeout(700);
    const s = await page.evaluate(() => ({
      wire: document.getElementById('wire').checked, cmap: document.getElementById('cmap').checked,
      tool: window.__tissue.tool, kind: window.__tissue.init.kind, building: !!window.__tissue.last.building,
    }));
    const said = (await notices(page, n0)).map((x) => x.message);
    check('shortcuts after the selector', s.wire !== w0 && s.cmap && s.tool === 'grasp' && s.kind === target && !s.building
      && !said.some((m) => m.includes('building')),
    `focus after the choice: ${focus || 'body'}; W -> wireframe ${s.wire}, C -> colours ${s.cmap}, 2 -> ${s.tool}, model ${s.kind}`
      + `${s.building ? ', a build running' : ''}${said.length ? `; notices: ${said.join(' | ')}` : ''}`);
    await page.keyboard.press('w');
    await page.keyboard.press('c');
    await page.keyboard.press('1');
  }

  // The switch matrix on this scene: every listed kind, live, a 2 s probe.
  const kinds = await page.evaluate(() => window.__tissue.init.kinds.map((k) => k.name));
  const matrix = [];
  for (const kind of kinds) {
    // While a long build runs, the status says what is being built and how far it got.
    const watch = page.evaluate(() => new Promise((resolve) => {
      const seen = { text: '', rate: [] };
      const t = setInterval(() => {
        const s = window.__tissue;
        if (s.buildText) { seen.text = s.buildText; seen.rate.push(s.last.sim_rate); }
        else if (seen.text && !s.last.building) { clearInterval(t); resolve(seen); }
      }, 250);
      setTimeout(() => { clearInterval(t); resolve(seen); }, 95000);
    }));
    const sw = await switchTo(page, kind);
    const seen = await Promise.race([watch, new Promise((r) => setTimeout(() => r({ text: '', rate: [] }), 500))]);
    if (sw.status === 'timeout') { check(`switch to ${kind}`, false, 'not running after 90 s'); matrix.push([kind, 'timeout']); continue; }
    if (sw.status === 'refused') {
      const reason = REFUSED[kind];
      check(`switch to ${kind}`, reason !== undefined && sw.reason.includes(reason), `refused: ${sw.reason}`);
      matrix.push([kind, `refused (${sw.reason.slice(0, 80)})`]);
      continue;
    }
    if (kind === 'hybrid') {
      // The region is coloured: the frames carry a part label per surface vertex, with the
      // cuttable region (2) and the pre-computed rest (0) both present.
      const labels = await page.evaluate(() => window.__tissue.last.labels || []);
      const parts = [0, 1, 2].map((p) => labels.filter((l) => l === p).length);
      check('hybrid region labels', parts[0] > 0 && parts[2] > 0, `rest ${parts[0]}, border ${parts[1]}, region ${parts[2]} surface vertices`);
    }
    const h = await holdProbe(page, 2000);
    if (!h) { check(`switch to ${kind}`, false, 'organ not under the pointer'); continue; }
    const ok = h.blowUps.length === 0 && h.max > 0 && h.max < FORCE_BOUND;
    const built = seen.text ? `; while building: "${seen.text}", old model ${Math.min(...seen.rate).toFixed(0)}-${Math.max(...seen.rate).toFixed(0)} steps/s` : '';
    check(`switch to ${kind}`, ok, `built in ${sw.ms} ms, probe 2 s: peak ${h.max.toFixed(4)} N (frames ${h.shown.toFixed(4)} N, press ${h.peak.toFixed(4)} N) over ${h.frames} frames, ${h.sim.toFixed(0)} steps/s, `
      + `haptic ${h.haptic.toFixed(0)} Hz, "${h.status}"${h.blowUps.length ? `; ${h.blowUps.join(' | ')}` : ''}${built}`);
    matrix.push([kind, ok ? `ok ${h.max.toFixed(3)} N` : `FAIL ${h.max.toFixed(3)} N ${h.blowUps[0] || ''}`]);
  }
  const scene = await page.evaluate(() => window.__tissue.init.scene.split('/').pop());
  info('switch matrix', `${scene}: ${matrix.map(([k, r]) => `${k}=${r}`).join('; ')}`);
  await page.waitForTimeout(1200);
  const fps = await page.evaluate(() => window.__tissue.fps || 0);
  info('page frame rate', `${fps.toFixed(1)} frames/s on ${scene} (SwiftShader, software WebGL)`);
  await page.close();
} finally {
  await browser.close();
}
process.exit(verdict() ? 1 : 0);
