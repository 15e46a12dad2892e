// Usage: node latency.mjs URL CHROMIUM CHAIR TRIALS
// Run by `intellwheels bench drive --browser-dir`: opens CHAIR's view and presses the on-screen
// joystick TRIALS times (real pointer events through the browser's input pipeline), forward and
// back in turn, releasing each press after about 0.6 s and waiting until the chair stands still.
// Prints one JSON line per press: the time the browser stamped on the pointerdown event that sent
// the drive (performance.timeOrigin + event.timeStamp, ms since the Unix epoch), which the bench
// pairs with the first wheel command after it. `clock_ms` is Date.now() minus the page's
// high-resolution clock read at once: how far the two clocks of the page disagree.
import { chromium } from "playwright-core";

const [url, executablePath, chair, trialsText] = process.argv.slice(2);
const trials = Number(trialsText);
const fail = (why) => { console.error("FAIL: " + why); process.exit(1); };
if (!(trials >= 1)) fail(`TRIALS must be a positive number, got ${trialsText}`);
const browser = await chromium.launch({ executablePath, headless: true, args: ["--no-sandbox"] });
try {
  const page = await browser.newPage({ viewport: { width: 1000, height: 900 } });
  page.on("pageerror", (e) => fail("page error: " + e.message));
  const target = new URL(url); target.searchParams.set("chair", chair);
  await page.goto(target.toString());
  await page.waitForFunction((n) => window.iw && window.iw.frames >= 2 && window.iw.last.chairs.some((c) => c.n === n), chair, { timeout: 60000 });
  await page.evaluate(() => {
    window.iw.pressed = [];
    document.getElementById("stick").addEventListener("pointerdown", (e) => window.iw.pressed.push(performance.timeOrigin + e.timeStamp), { capture: true });
  });
  const [cx, cy, r] = await page.evaluate(() => window.iw.stickCentre());
  const still = (n) => { const c = window.iw.last.chairs.find((c) => c.n === n); return c && Math.abs(c.v[0]) < 0.01 && Math.abs(c.v[1]) < 0.05; };
  for (let k = 0; k < trials; k++) {
    const dir = k % 2 === 0 ? 1 : -1;
    // moved there without a button first (no drive), so the press itself is the one input
    await page.mouse.move(cx, cy - dir * 0.8 * r);
    await page.mouse.down();
    // the hold varies so presses fall at different phases of the receivers' steps
    await page.waitForTimeout(600 + (k * 7) % 50);
    await page.mouse.up();
    await page.waitForTimeout(300);
    await page.waitForFunction(still, chair, { timeout: 15000 });
    await page.waitForTimeout(200);
    const [at, clock] = await page.evaluate((k) => [window.iw.pressed[k], Date.now() - (performance.timeOrigin + performance.now())], k);
    if (at === undefined) fail(`press ${k}: no pointerdown event seen`);
    console.log(JSON.stringify({ trial: k, dir, event_unix_ms: at, clock_ms: clock }));
  }
} finally {
  await browser.close();
}
