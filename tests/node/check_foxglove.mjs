// Field names are the schemas' own (snake_case), as protobufjs builds them from the
// descriptors.
//
// Checks slam-node's Foxglove live view with a client we did not write: Foxglove's own
// WebSocket client (@foxglove/ws-protocol, over `ws`), decoding every message with protobufjs
// from the FileDescriptorSet each protobuf channel carries (or JSON.parse for JSON channels).
//
//   node check_foxglove.mjs <out-dir> -- <slam-node command ...>
//
// The command must write its outputs to <out-dir> and serve the live view on a port it logs
// (`--foxglove-bind 127.0.0.1:0`), holding its start until a client subscribes to /slam/pose
// (`--foxglove-wait 30`). The script starts it, reads `ws://<address>` from its log,
// subscribes to every advertised channel (the pose last), decodes every message, and when the
// daemon has ended checks:
//   - every channel but /slam/trajectory_optimised (a run on submaps only) sent messages,
//     every one decoded, and their contents are consistent (image size, point stride, frames);
//   - the poses received on /slam/pose are trajectory.tum's, line for line, to the precision
//     it is printed with (time 1e-9 s as printed, within the 2.4e-7 s an f64 holds at 1.7e9;
//     x, y 1e-6 m; quaternion 1e-9).
// Exit status 0 when all holds, 1 otherwise.

import { spawn } from "node:child_process";
import { readFileSync } from "node:fs";
import { join } from "node:path";

import wsProtocol from "@foxglove/ws-protocol";
import protobuf from "protobufjs";
import descriptor from "protobufjs/ext/descriptor/index.js";
import WebSocket from "ws";

// The Foxglove SDK (0.30) names its WebSocket subprotocol `foxglove.sdk.v1`; its messages are
// those of the ws-protocol spec that @foxglove/ws-protocol implements.
const SUBPROTOCOL = "foxglove.sdk.v1";
const { FoxgloveClient } = wsProtocol;
const TIMEOUT_MS = 240_000;
const OPTIONAL_TOPICS = new Set(["/slam/trajectory_optimised"]);

const args = process.argv.slice(2);
const dash = args.indexOf("--");
if (dash !== 1 || args.length < 3) {
  console.error("usage: node check_foxglove.mjs <out-dir> -- <slam-node command ...>");
  process.exit(2);
}
const outDir = args[0];
const command = args.slice(2);

const failures = [];
const fail = (why) => {
  failures.push(why);
  console.error(`FAIL: ${why}`);
};

const channels = new Map(); // channel id -> { channel, decode }
const bySubscription = new Map(); // subscription id -> channel id
const received = new Map(); // topic -> count
const decodeErrors = new Map(); // topic -> first error
const poses = [];
const checks = { image: 0, cloud: 0, map: 0, tf: 0, counters: 0, covariance: 0 };

function decoderFor(channel) {
  if (channel.encoding === "json") {
    const text = new TextDecoder();
    return (bytes) => JSON.parse(text.decode(bytes));
  }
  if (channel.encoding === "protobuf") {
    const set = descriptor.FileDescriptorSet.decode(Buffer.from(channel.schema, "base64"));
    const root = protobuf.Root.fromDescriptor(set);
    const type = root.lookupType(channel.schemaName);
    return (bytes) =>
      type.toObject(type.decode(bytes), { longs: Number, enums: String, defaults: true });
  }
  throw new Error(`unexpected encoding ${channel.encoding}`);
}

const stampS = (t) => Number(t.seconds) + Number(t.nanos) * 1e-9;

function inspect(topic, m) {
  switch (topic) {
    case "/slam/pose":
      if (m.frame_id !== "map") fail(`pose in frame ${m.frame_id}`);
      poses.push({
        t: stampS(m.timestamp),
        x: m.pose.position.x,
        y: m.pose.position.y,
        qz: m.pose.orientation.z,
        qw: m.pose.orientation.w,
      });
      break;
    case "/radar/image":
      if (m.encoding !== "mono8" || m.data.length !== m.width * m.height || m.step !== m.width)
        fail(`image ${m.width}x${m.height} ${m.encoding} step ${m.step} with ${m.data.length} bytes`);
      checks.image += m.data.some((v) => v > 0) ? 1 : 0;
      break;
    case "/slam/detections":
      if (m.point_stride !== 16 || m.data.length % 16 !== 0 || m.frame_id !== "radar")
        fail(`detections: stride ${m.point_stride}, ${m.data.length} bytes, frame ${m.frame_id}`);
      checks.cloud += 1;
      break;
    case "/slam/map": {
      const e = m.entities[0];
      if (!e || e.frame_id !== "map" || e.cylinders.length !== e.spheres.length)
        fail(`map entity ${JSON.stringify(e && { frame: e.frame_id, c: e.cylinders.length })}`);
      checks.map += e && e.cylinders.length > 0 ? 1 : 0;
      break;
    }
    case "/tf": {
      const pairs = m.transforms.map((t) => `${t.parent_frame_id}>${t.child_frame_id}`).join(",");
      if (pairs !== "map>base_link,base_link>radar") fail(`tf ${pairs}`);
      checks.tf += 1;
      break;
    }
    case "/slam/counters":
      if (typeof m.diagnostics?.rotation !== "number" || typeof m.foxglove?.dropped !== "number")
        fail(`counters ${JSON.stringify(m).slice(0, 200)}`);
      checks.counters += 1;
      break;
    case "/slam/pose_covariance": {
      const c = m.covariance;
      const symmetric = c.length === 3 && c.every((row, i) => row.every((v, j) => v === c[j][i]));
      // The first poses may be exact (the map frame is anchored there): zero is allowed.
      if (!symmetric || !(c[0][0] >= 0 && c[1][1] >= 0 && c[2][2] >= 0))
        fail(`pose covariance not symmetric with a non-negative diagonal: ${JSON.stringify(c)}`);
      checks.covariance += c[0][0] > 0 && c[1][1] > 0 && c[2][2] > 0 ? 1 : 0;
      break;
    }
    default:
      break;
  }
}

function connect(url) {
  console.error(`connecting to ${url}`);
  const ws = new WebSocket(url, [SUBPROTOCOL]);
  const client = new FoxgloveClient({ ws });
  client.on("error", (e) => fail(`client error: ${e?.message ?? e}`));
  client.on("status", (s) => console.error(`server status: ${JSON.stringify(s)}`));
  client.on("advertise", (list) => {
    for (const channel of list) {
      let decode;
      try {
        decode = decoderFor(channel);
      } catch (e) {
        fail(`no decoder for ${channel.topic} (${channel.schemaName}): ${e.message}`);
        continue;
      }
      channels.set(channel.id, { channel, decode });
      received.set(channel.topic, 0);
    }
    // The pose last: the daemon starts its run on the pose's subscription.
    const ordered = [...channels.values()].sort(
      (a, b) => (a.channel.topic === "/slam/pose") - (b.channel.topic === "/slam/pose"),
    );
    for (const { channel } of ordered) {
      bySubscription.set(client.subscribe(channel.id), channel.id);
    }
  });
  client.on("message", ({ subscriptionId, data }) => {
    const entry = channels.get(bySubscription.get(subscriptionId));
    if (!entry) {
      fail(`message for unknown subscription ${subscriptionId}`);
      return;
    }
    const topic = entry.channel.topic;
    received.set(topic, received.get(topic) + 1);
    let m;
    try {
      m = entry.decode(new Uint8Array(data.buffer, data.byteOffset, data.byteLength));
    } catch (e) {
      if (!decodeErrors.has(topic)) decodeErrors.set(topic, e.message);
      return;
    }
    inspect(topic, m);
  });
  return ws;
}

function readTum(path) {
  return readFileSync(path, "utf8")
    .split("\n")
    .filter((l) => l.trim() && !l.startsWith("#"))
    .map((l) => {
      const text = l.trim().split(/\s+/);
      const v = text.map(Number);
      return { t: v[0], x: v[1], y: v[2], qz: v[6], qw: v[7], text };
    });
}

function comparePoses() {
  const tum = readTum(join(outDir, "trajectory.tum"));
  console.error(`trajectory.tum: ${tum.length} poses; received ${poses.length} on /slam/pose`);
  if (tum.length === 0) fail("trajectory.tum is empty");
  if (poses.length !== tum.length) fail(`received ${poses.length} poses, trajectory.tum has ${tum.length}`);
  let worst = { t: 0, xy: 0, q: 0 };
  const n = Math.min(poses.length, tum.length);
  for (let i = 0; i < n; i += 1) {
    const p = poses[i];
    const f = tum[i];
    const d = {
      t: Math.abs(p.t - f.t),
      xy: Math.max(Math.abs(p.x - f.x), Math.abs(p.y - f.y)),
      q: Math.max(Math.abs(p.qz - f.qz), Math.abs(p.qw - f.qw)),
    };
    worst = { t: Math.max(worst.t, d.t), xy: Math.max(worst.xy, d.xy), q: Math.max(worst.q, d.q) };
    // Printed: time %.9f, x and y %.6f, quaternion %.9f; half a unit of the last digit,
    // and for time the f64's own resolution at 1.7e9 s.
    if (d.t > 5e-7 || d.xy > 5e-7 + 1e-12 || d.q > 5e-10 + 1e-12) {
      fail(`pose ${i}: received ${JSON.stringify(p)}, trajectory.tum has ${f.text.join(" ")}`);
      break;
    }
  }
  console.error(
    `poses agree: worst |dt| ${worst.t.toExponential(2)} s, |dxy| ${worst.xy.toExponential(2)} m, |dq| ${worst.q.toExponential(2)}`,
  );
}

const daemon = spawn(command[0], command.slice(1), { stdio: ["ignore", "inherit", "pipe"] });
let ws = null;
let pending = "";
daemon.stderr.on("data", (chunk) => {
  process.stderr.write(chunk);
  pending += chunk.toString();
  const lines = pending.split("\n");
  pending = lines.pop();
  for (const line of lines) {
    const found = /Foxglove live view: (ws:\/\/[0-9.:[\]a-f]+)/.exec(line);
    if (found && !ws) ws = connect(found[1]);
  }
});
const timer = setTimeout(() => {
  fail(`the daemon did not end within ${TIMEOUT_MS / 1000} s`);
  daemon.kill("SIGKILL");
}, TIMEOUT_MS);

daemon.on("exit", (code, signal) => {
  clearTimeout(timer);
  // Let the last frames the server flushed before closing arrive.
  setTimeout(() => {
    if (code !== 0) fail(`the daemon exited with ${code ?? signal}`);
    if (!ws) fail("the daemon never logged its Foxglove address");
    if (ws) ws.close();
    if (channels.size < 10) fail(`only ${channels.size} channels advertised`);
    for (const [topic, n] of received) {
      console.error(`  ${topic}: ${n} messages`);
      if (n === 0 && !OPTIONAL_TOPICS.has(topic)) fail(`no message on ${topic}`);
    }
    for (const [topic, e] of decodeErrors) fail(`decoding ${topic}: ${e}`);
    for (const [what, n] of Object.entries(checks)) {
      if (n === 0) fail(`no ${what} message with content`);
    }
    if (ws) comparePoses();
    if (failures.length > 0) {
      console.error(`${failures.length} failure(s)`);
      process.exit(1);
    }
    console.error("Foxglove live view: every channel decoded, poses equal trajectory.tum");
    process.exit(0);
  }, 300);
});
