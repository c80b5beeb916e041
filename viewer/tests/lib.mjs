// Shared steps of the browser tests: launch Chromium (SwiftShader WebGL), open a `tissue
// view` page, switch models, hold the probe, and record checks.
import { chromium } from 'playwright-core';

export const results = [];
export function check(name, ok, detail) {
  results.push({ name, ok });
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${name}: ${detail}`);
}
export function info(name, detail) {
  console.log(`info ${name}: ${detail}`);
}

export async function launch() {
  return chromium.launch({
    executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
    headless: true,
    args: [
      '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
      '--disable-quic', '--no-first-run', '--disable-background-networking',
      '--disable-component-update', '--disable-sync',
    ],
  });
}

/// Opens the page; `warnings` collects the console's warnings (three.js's among them).
export async function open(browser, url) {
  const page = await browser.newPage({ viewport: { width: 1000, height: 700 } });
  page.warnings = [];
  page.requestsFailed = [];
  page.on('pageerror', (e) => console.log(`page error: ${e.message}`));
  page.on('console', (m) => { if (m.type() === 'warning' || m.type() === 'error') page.warnings.push(m.text()); });
  page.on('response', (r) => { if (r.status() >= 400) page.requestsFailed.push(`${r.status()} ${r.url()}`); });
  await page.goto(url);
  await page.waitForFunction(() => window.__tissue && window.__tissue.ready && window.__tissue.frames > 5,
    null, { timeout: 60000 });
  return page;
}

export const notices = (page, from) => page.evaluate((n) => window.__tissue.notices.slice(n), from);
export const noticeCount = (page) => page.evaluate(() => window.__tissue.notices.length);
/// What a blow-up or a rejected state says on the page.
export const BLOW_UP = /blew up|diverged|energy grew|implausible|not finite/i;

/// Switches the running model to `kind`: 'ok' once it runs, 'refused' with the reason, or
/// 'timeout'. Kinds are switched by the page's own selector, as a user would.
export async function switchTo(page, kind, timeoutMs = 90000) {
  const t0 = Date.now();
  const n0 = await noticeCount(page);
  const current = await page.evaluate(() => window.__tissue.init.kind);
  if (current === kind) return { status: 'ok', ms: 0 };
  await page.selectOption('#kind', kind);
  try {
    // Done when the server said it runs the new kind (it sends that after the new model's
    // init) and a frame after the build was drawn, or when the build failed.
    await page.waitForFunction(([k, n]) => {
      const said = window.__tissue.notices.slice(n).map((x) => x.message);
      if (said.some((m) => m.includes(`building ${k} failed`))) return true;
      return said.some((m) => m.startsWith(`now running ${k} `))
        && window.__tissue.init.kind === k && window.__tissue.last.kind === k && !window.__tissue.last.building;
    },
    [kind, n0], { timeout: timeoutMs, polling: 200 });
  } catch {
    return { status: 'timeout', ms: Date.now() - t0 };
  }
  const failure = (await notices(page, n0)).map((x) => x.message).find((m) => m.includes(`building ${kind} failed`));
  if (failure) return { status: 'refused', reason: failure, ms: Date.now() - t0 };
  return { status: 'ok', ms: Date.now() - t0 };
}

/// Holds the probe pressed on the organ's middle for `ms`; the largest force (`max`: the
/// larger of the largest force a frame showed, `shown`, and the server's peak of the press,
/// `peak`), the blow-up notices, the rates. Frames alone miss a short push back: on a loaded
/// machine the page draws 1-5 frames/s, and the spring-mass liver pushes ~1 mN for the
/// 0.3 s the probe goes in, then dents past it and touches it in bursts (docs/viewer.md).
export async function holdProbe(page, ms = 2000) {
  await page.keyboard.press('1');
  const q = await page.evaluate(() => window.__tissue.organScreenPoint());
  if (!q) return null;
  const n0 = await noticeCount(page);
  const skipped0 = await page.evaluate(() => window.__tissue.skippedFrames);
  const frames0 = await page.evaluate(() => window.__tissue.frames);
  await page.mouse.move(q[0], q[1]);
  await page.mouse.down();
  let shown = 0;
  let peak = 0;
  const t0 = Date.now();
  // At least `ms`, and at least 8 frames after the press (software WebGL on a loaded
  // machine draws a large organ at 1 frame/s), at most 20 s.
  const seen = async () => (await page.evaluate(() => window.__tissue.frames)) - frames0;
  while (Date.now() - t0 < ms || (Date.now() - t0 < Math.max(ms, 20000) && (await seen()) < 8)) {
    await page.waitForTimeout(100);
    const [f, p] = await page.evaluate(() => [window.__tissue.forceMagnitude, window.__tissue.pressPeak]);
    if (Number.isFinite(f)) shown = Math.max(shown, f); else shown = Infinity;
    if (Number.isFinite(p)) peak = Math.max(peak, p); else peak = Infinity;
  }
  const last = await page.evaluate(() => ({
    sim: window.__tissue.last.sim_rate, haptic: window.__tissue.last.haptic_rate,
    substeps: window.__tissue.last.substeps, dt: window.__tissue.last.dt, status: window.__tissue.status,
    skipped: window.__tissue.skippedFrames, frames: window.__tissue.frames,
  }));
  last.skipped -= skipped0;
  last.frames -= frames0;
  await page.mouse.up();
  await page.waitForTimeout(150);
  const said = (await notices(page, n0)).map((x) => x.message);
  return { max: Math.max(shown, peak), shown, peak, blowUps: said.filter((m) => BLOW_UP.test(m)), said, ...last };
}

export function verdict() {
  const failed = results.filter((r) => !r.ok).length;
  console.log(`page: ${results.length - failed} passed, ${failed} failed`);
  return failed;
}
