// Usage: node snapshot.mjs URL CHROMIUM AT_S OUT.png
// Saves a picture of the staff view once the served demo's simulated time reaches AT_S seconds
// (run the demo with `intellwheels --serve` so it goes in real time).
import { chromium } from "playwright-core";

const [url, executablePath, atS, out] = process.argv.slice(2);
const browser = await chromium.launch({ executablePath, headless: true, args: ["--no-sandbox"] });
try {
  const page = await browser.newPage({ viewport: { width: 1280, height: 720 } });
  await page.goto(url);
  await page.waitForFunction((t) => window.iw && window.iw.last && window.iw.last.t >= t, Number(atS), { timeout: 120000, polling: 100 });
  await page.screenshot({ path: out });
  console.log("snapshot at t = " + (await page.evaluate(() => window.iw.last.t)) + " s: " + out);
} finally {
  await browser.close();
}
