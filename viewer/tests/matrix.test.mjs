// The switch matrix on one scene: usage `node matrix.test.mjs URL [KIND...]` (default:
// every kind the page lists). Each kind is switched to live with the page's selector and
// the probe held on the organ for 2 s: ok (no blow-up notice, peak force below the
// bound), or refused with its reason. Not in CI (`scripts/browser-test.sh` runs the matrix
// on the probe liver only); `scripts/browser-test.sh --matrix` runs it on every scene.
import { launch, open, check, info, verdict, switchTo, holdProbe } from './lib.mjs';

const [url, ...only] = process.argv.slice(2);
const FORCE_BOUND = 3.0;
// A bem build on the smooth liver takes minutes on a loaded 2-core machine.
const SWITCH_MS = Number(process.env.MATRIX_SWITCH_MS || 150000);
const browser = await launch();
try {
  const page = await open(browser, url);
  const scene = await page.evaluate(() => window.__tissue.init.scene.split('/').pop());
  const kinds = only.length ? only : await page.evaluate(() => window.__tissue.init.kinds.map((k) => k.name));
  const row = [];
  for (const kind of kinds) {
    const sw = await switchTo(page, kind, SWITCH_MS);
    if (sw.status !== 'ok') {
      row.push(`${kind}=${sw.status}${sw.reason ? ` (${sw.reason.replace(/^building \S+ failed: /, '').slice(0, 70)})` : ''}`);
      check(`${scene} -> ${kind}`, sw.status === 'refused', sw.reason || `not running after ${SWITCH_MS / 1000} s`);
      continue;
    }
    const h = await holdProbe(page, 2000);
    if (!h) { row.push(`${kind}=no organ under the pointer`); check(`${scene} -> ${kind}`, false, 'organ not under the pointer'); continue; }
    // A probe pressed one radius into the organ must push back: a zero force means the
    // press never reached the model. The peak is the server's for the press beside the
    // frames' (a push of a few steps falls between slow frames: docs/viewer.md).
    const ok = h.blowUps.length === 0 && h.max < FORCE_BOUND && h.max > 0;
    row.push(`${kind}=${ok ? 'ok' : 'FAIL'} ${h.max.toFixed(3)} N`);
    check(`${scene} -> ${kind}`, ok, `built in ${sw.ms} ms; peak ${h.max.toFixed(4)} N (frames ${h.shown.toFixed(4)} N, press ${h.peak.toFixed(4)} N); "${h.status}"; ${h.sim.toFixed(0)} steps/s; ${h.frames} frames (${h.skipped} not shown)${h.blowUps.length ? `; ${h.blowUps[0]}` : ''}`);
  }
  info('switch matrix', `${scene}: ${row.join('; ')}`);
} finally {
  await browser.close();
}
process.exit(verdict() ? 1 : 0);
