// Usage: node deployment.mjs URL CHROMIUM SCREENSHOT.png
// The dashboard a deployment's services container serves (world, services and three chairs as
// processes; see ../deployment_dashboard.rs). The staff view must show all three chairs and see
// them move: chair-a and chair-b under goals the services gave, chair-c driven from its own view
// with the on-screen joystick (real pointer events, relayed over the bus to its interface agent)
// and released, after which it stands still. While driven, chair-c's view shows the command sent,
// what shared control applied and the sonar picture, all three from the bus. Saves a screenshot of the staff view.
import { chromium } from "playwright-core";

const [url, executablePath, screenshot] = process.argv.slice(2);
const fail = (why) => { console.error("FAIL: " + why); process.exit(1); };
const CHAIRS = ["chair-a", "chair-b", "chair-c"], DRIVEN = "chair-c";
const browser = await chromium.launch({ executablePath, headless: true, args: ["--no-sandbox"] });
try {
  const staff = await browser.newPage({ viewport: { width: 1280, height: 720 } });
  staff.on("pageerror", (e) => fail("staff view: page error: " + e.message));
  await staff.goto(url);
  await staff.waitForFunction((names) => window.iw && window.iw.frames >= 2 && names.every((n) => window.iw.last.chairs.some((c) => c.n === n)), CHAIRS, { timeout: 90000 });
  const poses = () => staff.evaluate(() => Object.fromEntries(window.iw.last.chairs.map((c) => [c.n, c.p])));
  const first = await poses();
  console.log("first seen:", JSON.stringify(first));
  const moved = (now, n) => Math.hypot(now[n][0] - first[n][0], now[n][1] - first[n][1]);
  const containers = await staff.evaluate(() => window.iw.last.containers.map((c) => `${c.name}: ${c.agents.length}`));
  console.log("containers:", containers.join(", "));

  // chair-c's own view: forward on the stick until the staff view sees it move, then let go.
  const own = await browser.newPage({ viewport: { width: 1000, height: 900 } });
  own.on("pageerror", (e) => fail("chair view: page error: " + e.message));
  const target = new URL(url); target.searchParams.set("chair", DRIVEN);
  await own.goto(target.toString());
  await own.waitForFunction((n) => window.iw && window.iw.frames >= 2 && window.iw.last.chairs.some((c) => c.n === n), DRIVEN, { timeout: 20000 });
  const [cx, cy, r] = await own.evaluate(() => window.iw.stickCentre());
  await own.mouse.move(cx, cy); await own.mouse.down(); await own.mouse.move(cx, cy - 0.6 * r, { steps: 4 });
  const pressed = Date.now();
  while (moved(await poses(), DRIVEN) < 0.25) {
    if (Date.now() - pressed > 30000) fail(`${DRIVEN} did not move while driven: ${JSON.stringify(await poses())}`);
    await own.waitForTimeout(100);
  }
  const shown = await own.evaluate((n) => window.iw.last.chairs.find((c) => c.n === n).d, DRIVEN);
  console.log(`${DRIVEN} driven ${((Date.now() - pressed) / 1000).toFixed(1)} s; its view shows ${JSON.stringify(shown)}`);
  if (!shown.user || shown.user[0] <= 0) fail("the chair view does not show the user's command: " + JSON.stringify(shown));
  // what shared control applied (told by the chair's control agent) and the sonar picture (its
  // perception agent's readings), both over the bus
  if (!shown.applied || shown.applied[0] <= 0) fail("the chair view does not show what shared control applied: " + JSON.stringify(shown));
  const sonar = await own.evaluate((n) => window.iw.last.chairs.find((c) => c.n === n).s, DRIVEN);
  console.log(`${DRIVEN} sonar (m): ${JSON.stringify(sonar)}`);
  if (sonar.length < 8 || !sonar.some((r) => r > 0 && r < 3)) fail("the chair view has no sonar picture: " + JSON.stringify(sonar));
  await own.mouse.up();
  // Released: the stop goes at once; the interface's 300 ms hold and the control agent's
  // watchdog stop it anyway. It must then stand still.
  await own.waitForTimeout(2000);
  const still = (await poses())[DRIVEN];
  await own.waitForTimeout(1500);
  const after = (await poses())[DRIVEN];
  const crept = Math.hypot(after[0] - still[0], after[1] - still[1]);
  console.log(`${DRIVEN} released: moved ${crept.toFixed(3)} m in the 1.5 s after it settled`);
  if (crept > 0.05) fail(`${DRIVEN} still moving after release: ${crept} m`);

  // The others move under their goals.
  const start = Date.now();
  for (;;) {
    const now = await poses();
    const m = Object.fromEntries(CHAIRS.map((n) => [n, moved(now, n)]));
    if (CHAIRS.every((n) => m[n] > 0.25)) { console.log("moved (m):", JSON.stringify(m)); break; }
    if (Date.now() - start > 90000) fail("not every chair moved: " + JSON.stringify(m));
    await staff.waitForTimeout(250);
  }
  const msgs = await staff.evaluate(() => window.iw.last.msgs.length);
  const sent = await staff.evaluate(() => window.iw.last.sent);
  console.log(`sniffer: ${msgs} recent of ${sent} messages`);
  if (sent === 0) fail("the staff view saw no message between containers");
  await staff.screenshot({ path: screenshot });
  console.log("screenshot: " + screenshot);
} finally {
  await browser.close();
}
