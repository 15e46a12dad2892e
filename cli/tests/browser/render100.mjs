// Usage: node render100.mjs URL CHROMIUM
// A benchmark, not a test: how long the staff view takes to handle one websocket frame (parse,
// side panels, map) with 100 chairs, against the live frame of the demo as the peer, in headless
// chromium. Prints medians and p99 over 200 frames each; the dashboard sends 10 frames a second.
import { chromium } from "playwright-core";

const [url, executablePath] = process.argv.slice(2);
const browser = await chromium.launch({ executablePath, headless: true, args: ["--no-sandbox"] });
try {
  const page = await browser.newPage({ viewport: { width: 1280, height: 720 } });
  await page.goto(url);
  await page.waitForFunction(() => window.iw && window.iw.frames >= 2, null, { timeout: 15000 });
  const result = await page.evaluate(() => {
    ws.onmessage = null; // only the frames timed here from now on
    const live = window.iw.last;
    const chairs = [];
    for (let i = 0; i < 100; i++) {
      const c = JSON.parse(JSON.stringify(live.chairs[i % live.chairs.length]));
      c.n = "chair-" + i;
      c.p = [1 + (i % 20) * 0.9, 1 + Math.floor(i / 20) * 2.2, c.p[2]];
      chairs.push(c);
    }
    const time = (frame) => {
      const ms = [];
      for (let k = 0; k < 200; k++) {
        const t0 = performance.now();
        state = JSON.parse(frame);
        sidebar();
        draw();
        ms.push(performance.now() - t0);
      }
      ms.sort((a, b) => a - b);
      return { bytes: frame.length, median_ms: ms[100], p99_ms: ms[198] };
    };
    return { live: { chairs: live.chairs.length, ...time(JSON.stringify(live)) }, hundred: { chairs: 100, ...time(JSON.stringify({ ...live, chairs })) } };
  });
  console.log(JSON.stringify(result));
} finally {
  await browser.close();
}
