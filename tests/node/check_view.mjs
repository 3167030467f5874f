// Opens slam-node's live view page (--view) in Debian's Chromium driven by Playwright
// (playwright-core: no browser download; CHROMIUM names the executable, default
// /usr/bin/chromium), during a short real-time run:
//
//   node check_view.mjs <out-dir> <screenshot.png> -- <slam-node command ...>
//
// The command must serve the view on a port it logs (`--view --foxglove-bind 127.0.0.1:0`)
// and hold its start until the page subscribes (`--foxglove-wait 60`). Checks: the radar
// image and the map are drawn; the pose the page shows moves, and each pose it showed is a
// line of trajectory.tum (time to 5e-7 s, x and y to 1e-6 m); no page error. Keeps a
// screenshot. Exit status 0 when all holds.

import { spawn } from "node:child_process";
import { readFileSync } from "node:fs";
import { join } from "node:path";

import { chromium } from "playwright-core";

const TIMEOUT_MS = 180_000;
const args = process.argv.slice(2);
if (args[2] !== "--" || args.length < 4) {
  console.error("usage: node check_view.mjs <out-dir> <screenshot.png> -- <slam-node command ...>");
  process.exit(2);
}
const [outDir, screenshot] = args;
const command = args.slice(3);
const failures = [];
const fail = (why) => {
  failures.push(why);
  console.error(`FAIL: ${why}`);
};

const daemon = spawn(command[0], command.slice(1), { stdio: ["ignore", "inherit", "pipe"] });
const exited = new Promise((resolve) => daemon.on("exit", (code, signal) => resolve(code ?? signal)));
const address = await new Promise((resolve, reject) => {
  let pending = "";
  daemon.stderr.on("data", (chunk) => {
    process.stderr.write(chunk);
    pending += chunk.toString();
    const found = /live view page at (http:\/\/[0-9.:]+\/)/.exec(pending);
    if (found) resolve(found[1]);
  });
  daemon.on("exit", () => reject(new Error("the daemon ended before logging its page")));
  setTimeout(() => reject(new Error("no page address logged")), 60_000);
});

const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM ?? "/usr/bin/chromium",
  args: ["--no-sandbox"],
});
const page = await browser.newPage({ viewport: { width: 1010, height: 640 } });
page.on("pageerror", (e) => fail(`page error: ${e.message}`));
console.error(`opening ${address}`);
await page.goto(address);

// Sample what the page shows while the run goes.
const shown = [];
let ended = false;
exited.then(() => {
  ended = true;
});
const deadline = Date.now() + TIMEOUT_MS;
while (!ended && Date.now() < deadline) {
  const s = await page.evaluate(() => ({
    images: window.slamView.images,
    maps: window.slamView.maps,
    poses: window.slamView.poses,
    features: window.slamView.features.length,
    pose: window.slamView.lastPose,
    error: window.slamView.error,
  }));
  if (s.error) fail(`view: ${s.error}`);
  if (s.pose && (shown.length === 0 || shown[shown.length - 1].pose.t !== s.pose.t)) shown.push(s);
  await new Promise((r) => setTimeout(r, 100));
}
const code = await exited;
const last = await page.evaluate(() => ({
  images: window.slamView.images,
  maps: window.slamView.maps,
  features: window.slamView.features.length,
  poses: window.slamView.poses,
}));
await page.screenshot({ path: screenshot });
await browser.close();

if (code !== 0) fail(`the daemon exited with ${code}`);
console.error(`page drew ${last.images} radar images, ${last.maps} maps (${last.features} features), ${last.poses} poses; sampled ${shown.length} distinct poses`);
if (last.images === 0) fail("no radar image drawn");
if (last.maps === 0 || last.features === 0) fail("no map drawn");
if (shown.length < 5) fail(`only ${shown.length} distinct poses seen`);
const tum = readFileSync(join(outDir, "trajectory.tum"), "utf8")
  .split("\n")
  .filter((l) => l.trim() && !l.startsWith("#"))
  .map((l) => l.trim().split(/\s+/).map(Number));
for (const { pose } of shown) {
  const line = tum.find((v) => Math.abs(v[0] - pose.t) < 5e-7);
  if (!line) {
    fail(`pose at ${pose.t} is not in trajectory.tum`);
  } else if (Math.abs(line[1] - pose.x) > 1e-6 || Math.abs(line[2] - pose.y) > 1e-6) {
    fail(`pose at ${pose.t}: page ${pose.x}, ${pose.y}, trajectory.tum ${line[1]}, ${line[2]}`);
  }
}
if (shown.length >= 2) {
  const a = shown[0].pose;
  const b = shown[shown.length - 1].pose;
  const moved = Math.hypot(b.x - a.x, b.y - a.y);
  console.error(`the pose shown moved ${moved.toFixed(2)} m over ${(b.t - a.t).toFixed(1)} s`);
  if (!(moved > 1)) fail(`the pose shown moved only ${moved} m`);
}
console.error(`screenshot: ${screenshot}`);
if (failures.length > 0) {
  console.error(`${failures.length} failure(s)`);
  process.exit(1);
}
console.error("live view page: radar image and map drawn, the pose shown follows trajectory.tum");
