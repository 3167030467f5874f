// The live view page: connects to the Foxglove WebSocket on the address that served it
// (slam-node --view), subscribes to the radar image, the map, the pose and the trajectory,
// decodes them with protobufjs from the FileDescriptorSet each channel carries, and draws
// them on two canvases. `npm run build` bundles this file into
// ../src/output/foxglove/view/view.js, which slam-node embeds.
//
// For tests, `window.slamView` holds what has been drawn: counts of images, maps and poses,
// the last pose, and the state of the connection.

import { FoxgloveClient } from "@foxglove/ws-protocol";
import protobuf from "protobufjs";
import descriptor from "protobufjs/ext/descriptor";

const SUBPROTOCOL = "foxglove.sdk.v1";
const WANTED = ["/radar/image", "/slam/map", "/slam/pose", "/slam/trajectory"];

const state = {
  connected: false,
  images: 0,
  maps: 0,
  poses: 0,
  lastPose: null,
  features: [],
  trajectory: [],
  error: null,
};
window.slamView = state;

const status = document.getElementById("status");
const radar = document.getElementById("radar");
const world = document.getElementById("world");

function show(text) {
  status.textContent = text;
}

function decoderFor(channel) {
  const set = descriptor.FileDescriptorSet.decode(
    Uint8Array.from(atob(channel.schema), (c) => c.charCodeAt(0)),
  );
  const type = protobuf.Root.fromDescriptor(set).lookupType(channel.schemaName);
  return (bytes) => type.toObject(type.decode(bytes), { longs: Number, defaults: true });
}

function drawImage(m) {
  const ctx = radar.getContext("2d");
  radar.width = m.width;
  radar.height = m.height;
  const img = ctx.createImageData(m.width, m.height);
  for (let i = 0; i < m.width * m.height; i += 1) {
    const v = m.data[i];
    img.data[4 * i] = v;
    img.data[4 * i + 1] = v;
    img.data[4 * i + 2] = v;
    img.data[4 * i + 3] = 255;
  }
  ctx.putImageData(img, 0, 0);
  state.images += 1;
}

// The world view: x east to the right, y north up, scaled to hold the map and the trajectory.
function drawWorld() {
  const ctx = world.getContext("2d");
  const w = world.width;
  const h = world.height;
  ctx.fillStyle = "#111";
  ctx.fillRect(0, 0, w, h);
  const xs = [];
  const ys = [];
  for (const f of state.features) {
    xs.push(f.x);
    ys.push(f.y);
  }
  for (const p of state.trajectory) {
    xs.push(p.x);
    ys.push(p.y);
  }
  if (state.lastPose) {
    xs.push(state.lastPose.x);
    ys.push(state.lastPose.y);
  }
  if (xs.length === 0) return;
  const pad = 10;
  const minX = Math.min(...xs) - pad;
  const maxX = Math.max(...xs) + pad;
  const minY = Math.min(...ys) - pad;
  const maxY = Math.max(...ys) + pad;
  const scale = Math.min(w / (maxX - minX), h / (maxY - minY));
  const px = (x) => (x - minX) * scale + (w - (maxX - minX) * scale) / 2;
  const py = (y) => h - ((y - minY) * scale + (h - (maxY - minY) * scale) / 2);
  for (const f of state.features) {
    ctx.save();
    ctx.translate(px(f.x), py(f.y));
    ctx.rotate(-f.angle);
    ctx.beginPath();
    ctx.ellipse(0, 0, Math.max(1, (f.a / 2) * scale), Math.max(1, (f.b / 2) * scale), 0, 0, 2 * Math.PI);
    ctx.fillStyle = f.fill;
    ctx.fill();
    ctx.restore();
    ctx.fillStyle = f.dot;
    ctx.fillRect(px(f.x) - 2, py(f.y) - 2, 4, 4);
  }
  ctx.strokeStyle = "#4af";
  ctx.lineWidth = 2;
  ctx.beginPath();
  state.trajectory.forEach((p, i) => (i === 0 ? ctx.moveTo(px(p.x), py(p.y)) : ctx.lineTo(px(p.x), py(p.y))));
  ctx.stroke();
  const p = state.lastPose;
  if (p) {
    ctx.save();
    ctx.translate(px(p.x), py(p.y));
    ctx.rotate(-p.theta);
    ctx.fillStyle = "#fff";
    ctx.beginPath();
    ctx.moveTo(12, 0);
    ctx.lineTo(-8, 6);
    ctx.lineTo(-8, -6);
    ctx.closePath();
    ctx.fill();
    ctx.restore();
  }
}

const yaw = (q) => 2 * Math.atan2(q.z, q.w);
const rgba = (c, a) =>
  `rgba(${Math.round(255 * c.r)},${Math.round(255 * c.g)},${Math.round(255 * c.b)},${a})`;

const handlers = {
  "/radar/image": drawImage,
  "/slam/map": (m) => {
    const e = m.entities[0];
    if (!e) return;
    state.features = e.cylinders.map((c, i) => ({
      x: c.pose.position.x,
      y: c.pose.position.y,
      angle: yaw(c.pose.orientation),
      a: c.size.x,
      b: c.size.y,
      fill: rgba(c.color, 0.35),
      dot: rgba(e.spheres[i]?.color ?? c.color, 1),
    }));
    state.maps += 1;
    drawWorld();
  },
  "/slam/pose": (m) => {
    const t = Number(m.timestamp.seconds) + Number(m.timestamp.nanos) * 1e-9;
    state.lastPose = { t, x: m.pose.position.x, y: m.pose.position.y, theta: yaw(m.pose.orientation) };
    state.poses += 1;
    const p = state.lastPose;
    show(`x ${p.x.toFixed(2)} m, y ${p.y.toFixed(2)} m, heading ${((p.theta * 180) / Math.PI).toFixed(1)} deg; ` +
      `${state.images} radar images, ${state.maps} maps (${state.features.length} features), ${state.poses} poses`);
    drawWorld();
  },
  "/slam/trajectory": (m) => {
    state.trajectory = m.poses.map((p) => ({ x: p.position.x, y: p.position.y }));
  },
};

function start() {
  const ws = new WebSocket(`ws://${window.location.host}/`, [SUBPROTOCOL]);
  const client = new FoxgloveClient({ ws });
  const subscriptions = new Map();
  client.on("open", () => {
    state.connected = true;
    show("connected; waiting for data");
  });
  client.on("close", () => {
    state.connected = false;
    show(`disconnected (the run ended?) after ${state.poses} poses`);
  });
  client.on("error", (e) => {
    state.error = String(e?.message ?? e);
  });
  client.on("advertise", (channels) => {
    for (const channel of channels) {
      if (!WANTED.includes(channel.topic) || channel.encoding !== "protobuf") continue;
      const decode = decoderFor(channel);
      const handle = handlers[channel.topic];
      subscriptions.set(client.subscribe(channel.id), (bytes) => handle(decode(bytes)));
    }
  });
  client.on("message", ({ subscriptionId, data }) => {
    const on = subscriptions.get(subscriptionId);
    if (!on) return;
    try {
      on(new Uint8Array(data.buffer, data.byteOffset, data.byteLength));
    } catch (e) {
      state.error = String(e?.message ?? e);
    }
  });
}

start();
