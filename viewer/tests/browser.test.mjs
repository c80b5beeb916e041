// End-to-end test of `tissue view` in headless Chromium (driven by playwright-core; the
// browser is Debian's /usr/bin/chromium). Usage: node browser.test.mjs URL SCREENSHOT.png
// Checks: the liver renders (its pixels are in the frame), malformed and oversized messages
// are rejected with an error on the page while the simulation keeps running, a scripted
// grasp-and-drag moves vertices and the shown force becomes non-zero.
import { chromium } from 'playwright-core';

const [url, shot] = process.argv.slice(2);
const results = [];
function check(name, ok, detail) {
  results.push({ name, ok });
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${name}: ${detail}`);
}

const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  headless: true,
  args: [
    '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
    '--disable-quic', '--no-first-run', '--disable-background-networking',
    '--disable-component-update', '--disable-sync',
  ],
});
try {
  const page = await browser.newPage({ viewport: { width: 1000, height: 700 } });
  page.on('pageerror', (e) => console.log(`page error: ${e.message}`));
  await page.goto(url);
  await page.waitForFunction(() => window.__tissue && window.__tissue.ready && window.__tissue.frames > 5,
    null, { timeout: 60000 });
  const webgl2 = await page.evaluate(() => !!document.createElement('canvas').getContext('webgl2'));
  check('WebGL 2', webgl2, webgl2 ? 'available' : 'missing');

  const px = await page.evaluate(() => window.__tissue.organPixels());
  const share = px.organ / px.total;
  check('the liver renders', share > 0.005, `${px.organ} of ${px.total} pixels have the tissue colour (${(100 * share).toFixed(2)} %)`);
  await page.screenshot({ path: shot });

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

  // A scripted grasp and drag.
  await page.keyboard.press('2');
  const p = await page.evaluate(() => window.__tissue.organScreenPoint());
  check('organ under the pointer', !!p, JSON.stringify(p));
  if (p) {
    const d0 = await page.evaluate(() => window.__tissue.maxDisplacement || 0);
    await page.mouse.move(p[0], p[1]);
    await page.mouse.down();
    for (let k = 1; k <= 10; k++) {
      await page.mouse.move(p[0] + 6 * k, p[1] - 4 * k);
      await page.waitForTimeout(50);
    }
    await page.waitForTimeout(1500);
    const s = await page.evaluate(() => ({
      disp: window.__tissue.maxDisplacement,
      force: window.__tissue.forceMagnitude,
      shown: document.getElementById('force').textContent,
      size: window.__tissue.init.size,
    }));
    check('drag moves vertices', s.disp > 0.02 * s.size && s.disp > d0,
      `max displacement ${(1000 * s.disp).toFixed(2)} mm (organ size ${(1000 * s.size).toFixed(0)} mm)`);
    const shown = parseFloat(s.shown);
    check('shown force is non-zero', shown > 0 && s.force > 0, `force shown "${s.shown}"`);
    await page.mouse.up();
  }
  // The page's own frame rate (software WebGL here: a floor, not what a GPU gives).
  await page.waitForTimeout(1200);
  const fps = await page.evaluate(() => window.__tissue.fps || 0);
  // Informational: software rendering on a shared CI machine says little about a GPU.
  console.log(`info page frame rate: ${fps.toFixed(1)} frames/s (SwiftShader, software WebGL)`);

  // A scalpel path: a model that refuses cutting says so on the page.
  await page.keyboard.press('3');
  const c = await page.evaluate(() => window.__tissue.organScreenPoint());
  if (c) {
    const kind = await page.evaluate(() => window.__tissue.init.kind);
    const n0 = await page.evaluate(() => window.__tissue.notices.length);
    await page.mouse.move(c[0] - 40, c[1]);
    await page.mouse.down();
    for (let k = 0; k <= 16; k++) await page.mouse.move(c[0] - 40 + 5 * k, c[1] + 2 * k);
    await page.mouse.up();
    await page.waitForFunction((n) => window.__tissue.notices.length > n, n0, { timeout: 10000 }).catch(() => {});
    const said = await page.evaluate((n) => window.__tissue.notices.slice(n).map((x) => x.message), n0);
    check('scalpel answered', said.some((m) => m.includes('cannot cut') || m.includes('cut')),
      `${kind}: ${said.join(' | ')}`);
  }

  // Every model kind the server lists: switch to it live, push the probe in, feel a force.
  const kinds = await page.evaluate(() => window.__tissue.init.kinds.map((k) => k.name));
  await page.keyboard.press('1');
  // Kinds that cannot represent a closed organ must refuse it with the reason on the page.
  // hybrid needs its cut region from a scene (or scalpels to grow it around); a live switch has neither.
  const refusesClosedOrgan = { spline: 'genus', hybrid: 'cut_region' };
  for (const kind of kinds) {
    const t0 = Date.now();
    const n0 = await page.evaluate(() => window.__tissue.notices.length);
    await page.evaluate((k) => window.__tissue.send({ type: 'set_model', kind: k }), kind);
    try {
      await page.waitForFunction(([k, n]) =>
        (window.__tissue.init.kind === k && !window.__tissue.last.building)
        || window.__tissue.notices.slice(n).some((x) => x.message.includes(`building ${k} failed`)),
      [kind, n0], { timeout: 60000 });
    } catch {
      check(`model ${kind}`, false, 'not running after 60 s');
      continue;
    }
    const failure = await page.evaluate(([k, n]) => window.__tissue.notices.slice(n)
      .map((x) => x.message).find((m) => m.includes(`building ${k} failed`)), [kind, n0]);
    if (failure) {
      const reason = refusesClosedOrgan[kind];
      check(`model ${kind}`, reason !== undefined && failure.includes(reason), `refused: ${failure}`);
      continue;
    }
    const built = Date.now() - t0;
    const q = await page.evaluate(() => window.__tissue.organScreenPoint());
    if (!q) { check(`model ${kind}`, false, 'organ not under the pointer'); continue; }
    await page.mouse.move(q[0], q[1]);
    await page.mouse.down();
    let f = 0;
    for (let k = 0; k < 40 && !(f > 0); k++) {
      await page.waitForTimeout(100);
      f = await page.evaluate(() => window.__tissue.forceMagnitude);
    }
    const rates = await page.evaluate(() => [window.__tissue.last.sim_rate, window.__tissue.last.haptic_rate]);
    await page.mouse.up();
    check(`model ${kind}`, f > 0, `built and running in ${built} ms, probe force ${f.toFixed(4)} N, `
      + `${rates[0].toFixed(0)} steps/s, haptic ${rates[1].toFixed(0)} Hz`);
    await page.waitForTimeout(200);
  }
  await page.close();
} finally {
  await browser.close();
}
const failed = results.filter((r) => !r.ok).length;
console.log(`page: ${results.length - failed} passed, ${failed} failed`);
process.exit(failed ? 1 : 0);
