// The viewer on other scenes: usage `node scenes.test.mjs URL...` (one `tissue view`
// server per scene). On every scene the page's frame rate (SwiftShader: software WebGL, a
// floor) and that the organ renders; on the cut scenes, a scalpel drawn over the organ
// opens an incision that shows (the frame changes far more than while idle, and the
// surface changes; lips of a surface cut are open edges, drawn dark), then Reset and a grasp-and-drag raise no false blow-up.
import { launch, open, check, info, verdict, noticeCount, notices, BLOW_UP } from './lib.mjs';

const urls = process.argv.slice(2);
const browser = await launch();
try {
  for (const url of urls) {
    const page = await open(browser, url);
    const scene = await page.evaluate(() => window.__tissue.init.scene.split('/').pop());
    const kind = await page.evaluate(() => window.__tissue.init.kind);
    const nverts = await page.evaluate(() => window.__tissue.init.rest.length / 3);
    const px = await page.evaluate(() => window.__tissue.organPixels());
    check(`${scene}: the organ renders`, px.organ > 0.005 * px.total, `${px.organ} of ${px.total} pixels tissue-coloured`);
    await page.waitForTimeout(2500);
    const fps = await page.evaluate(() => window.__tissue.fps || 0);
    info(`${scene} frame rate`, `${fps.toFixed(1)} frames/s, ${nverts} surface vertices (SwiftShader)`);
    if (!scene.includes('cut')) { await page.close(); continue; }

    // The incision.
    await page.keyboard.press('3');
    const c = await page.evaluate(() => window.__tissue.organScreenPoint());
    if (!c) { check(`${scene}: cut`, false, 'organ not under the pointer'); await page.close(); continue; }
    await page.evaluate(() => window.__tissue.snapshot('a'));
    await page.waitForTimeout(800);
    await page.evaluate(() => window.__tissue.snapshot('b'));
    const idle = await page.evaluate(() => window.__tissue.changedPixels('a', 'b'));
    const inits0 = await page.evaluate(() => window.__tissue.inits);
    const n0 = await noticeCount(page);
    const t0 = Date.now();
    await page.mouse.move(c[0] - 60, c[1] - 10);
    await page.mouse.down();
    for (let k = 0; k <= 24; k++) { await page.mouse.move(c[0] - 60 + 5 * k, c[1] - 10 + k); await page.waitForTimeout(10); }
    await page.mouse.up();
    await page.waitForFunction((n) => window.__tissue.notices.slice(n).some((x) => /cut is done|cannot cut|cutting failed|stopped/.test(x.message)),
      n0, { timeout: 60000, polling: 100 }).catch(() => {});
    const doneMs = Date.now() - t0;
    await page.waitForTimeout(300);
    const s = await page.evaluate(() => ({ inits: window.__tissue.inits, open: window.__tissue.openEdges }));
    await page.evaluate(() => window.__tissue.snapshot('d'));
    const changed = await page.evaluate(() => window.__tissue.changedPixels('b', 'd'));
    const said = (await notices(page, n0)).map((x) => x.message);
    check(`${scene}: incision visible (${kind})`, s.inits > inits0 && changed > 3 * idle + 100,
      `${changed} pixels changed by the cut (${idle} while idle), ${s.open} open edges on the surface, `
      + `${s.inits - inits0} new surfaces, cut answered in ${doneMs} ms: ${said.join(' | ')}`);
    await page.screenshot({ path: `${process.env.SHOTS || '/tmp'}/cut-${scene.replace('.toml', '')}.png` });

    // Reset, then grasp and drag: no false blow-up (issue 23, item 4).
    const n1 = await noticeCount(page);
    await page.keyboard.press('r');
    await page.waitForTimeout(500);
    await page.keyboard.press('2');
    const p = await page.evaluate(() => window.__tissue.organScreenPoint());
    if (p) {
      await page.mouse.move(p[0], p[1]);
      await page.mouse.down();
      for (let k = 1; k <= 10; k++) { await page.mouse.move(p[0] + 5 * k, p[1] - 3 * k); await page.waitForTimeout(60); }
      await page.waitForTimeout(1000);
      const f = await page.evaluate(() => window.__tissue.forceMagnitude);
      await page.mouse.up();
      const bad = (await notices(page, n1)).map((x) => x.message).filter((m) => BLOW_UP.test(m));
      // Issue 23 item 4: from rest, round-off once read as a blow-up (0 to 4e-36 J); the
      // integrator's one-step check now has the growth watch's absolute floor.
      check(`${scene}: no blow-up after Reset`, bad.length === 0 && f > 0, `grasp force ${f.toFixed(4)} N; ${bad.length} blow-up notices${bad.length ? `: ${bad[0]}` : ''}`);
    }
    await page.close();
  }
} finally {
  await browser.close();
}
process.exit(verdict() ? 1 : 0);
