// Usage: node dashboard.mjs URL CHROMIUM SCREENSHOT.png
// Loads the dashboard, checks chairs move between two frames, clicks a place on the map for the
// selected chair and checks the chair takes that goal and turns; saves a screenshot.
import { chromium } from "playwright-core";

const [url, executablePath, screenshot] = process.argv.slice(2);
const fail = (why) => { console.error("FAIL: " + why); process.exit(1); };
const browser = await chromium.launch({ executablePath, headless: true, args: ["--no-sandbox"] });
try {
  const page = await browser.newPage({ viewport: { width: 1280, height: 720 } });
  page.on("pageerror", (e) => fail("page error: " + e.message));
  await page.goto(url);
  await page.waitForFunction(() => window.iw && window.iw.frames >= 2, null, { timeout: 15000 });
  const before = await page.evaluate(() => window.iw.last.chairs.map((c) => c.p));
  await page.waitForTimeout(1500);
  const after = await page.evaluate(() => window.iw.last.chairs.map((c) => c.p));
  const moved = before.map((p, i) => Math.hypot(after[i][0] - p[0], after[i][1] - p[1]));
  console.log("moved between two frames (m):", moved.map((m) => m.toFixed(2)).join(" "));
  if (!moved.some((m) => m > 0.05)) fail("no chair moved between two frames 1.5 s apart");

  // chair-0 (sent to the dining hall) is re-sent to the office: a place behind it
  const chair = "chair-0";
  await page.selectOption("#chair", chair);
  const map = await page.evaluate(() => fetch("/map.json" + location.search).then((r) => r.json()));
  const office = map.places.find((p) => p.name === "office");
  if (!office) fail("no `office` place in the map");
  const heading0 = await page.evaluate((n) => window.iw.last.chairs.find((c) => c.n === n).p[2], chair);
  const [sx, sy] = await page.evaluate(([x, y]) => window.iw.toScreen(x, y), office.at);
  await page.mouse.click(sx, sy);
  await page.waitForFunction(
    ([n, x, y]) => { const c = window.iw.last.chairs.find((c) => c.n === n); return c.g && Math.hypot(c.g[0] - x, c.g[1] - y) < 0.6; },
    [chair, office.at[0], office.at[1]], { timeout: 10000 });
  console.log("goal taken:", chair, "->", office.name);
  await page.waitForFunction(
    ([n, h0]) => { const c = window.iw.last.chairs.find((c) => c.n === n); return Math.abs(Math.atan2(Math.sin(c.p[2] - h0), Math.cos(c.p[2] - h0))) > 0.3; },
    [chair, heading0], { timeout: 20000 });
  const heading1 = await page.evaluate((n) => window.iw.last.chairs.find((c) => c.n === n).p[2], chair);
  console.log(`heading ${heading0.toFixed(2)} -> ${heading1.toFixed(2)} rad: turned`);
  await page.screenshot({ path: screenshot });
  console.log("screenshot: " + screenshot);
} finally {
  await browser.close();
}
