#!/usr/bin/env python3
"""Receives slam-node's live pose over Zenoh with readers we did not write.

    python3 tests/python/check_zenoh.py path/to/slam-node OUT_DIR

The binary must be built with `--features zenoh`. The daemon runs against its embedded
simulator in real time with `[output.zenoh]` listening on `tcp/127.0.0.1:0` (no port is
picked in advance); it logs the port it got, and a Python `eclipse-zenoh` peer (multicast
scouting off, no router) connects there. Two runs, one per key convention:

1. `ros2dds` (the default): poses arrive on the key `slam/odometry` (zenoh-bridge-ros2dds's
   key for the ROS 2 topic `/slam/odometry`) with the encoding `application/cdr`.
2. `rosbags` decodes every payload as `nav_msgs/msg/Odometry` with its own ROS 2 type store
   (the 4-byte CDR header and all), frames `map` and `base_link`.
3. Each pose received is the TUM trajectory's line at its time (x, y to 2e-6 m).
4. `/tf` and `/slam/map` decode as `tf2_msgs/msg/TFMessage` and `sensor_msgs/msg/PointCloud2`.
5. `rmw_zenoh`: every key is `0/<topic>/<pkg>::msg::dds_::<Type>_/<hash>` with the hash
   rosbags computes (`hash_rihs01`) for the type it decodes as, each sample carries
   rmw_zenoh's 33-byte attachment, and the node's liveliness token is in the graph.

Prints one line per check and `N passed, M failed`; exits 1 on any failure.
"""

import os
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import zenoh
from rosbags.typesys import Stores, get_typestore

from checklist import check, finish  # noqa: E402
TYPES = {
    "slam/odometry": "nav_msgs/msg/Odometry",
    "tf": "tf2_msgs/msg/TFMessage",
    "tf_static": "tf2_msgs/msg/TFMessage",
    "slam/map": "sensor_msgs/msg/PointCloud2",
    "slam/map_covariance": "visualization_msgs/msg/MarkerArray",
    "slam/detections": "sensor_msgs/msg/PointCloud2",
}


def run_daemon(binary, out, name, convention, duration_s):
    """Runs the daemon listening on 127.0.0.1:0 and a subscriber connected to the port it
    logs; returns (return code, stderr tail, samples, liveliness keys)."""
    config = out / f"{name}.toml"
    config.write_text(
        "[output]\npictures = false\nprogress = false\n\n[output.zenoh]\nenabled = true\n"
        f'connect = []\nlisten = ["tcp/127.0.0.1:0"]\nmulticast_scouting = false\nconvention = "{convention}"\n'
    )
    proc = subprocess.Popen(
        [str(binary), "--config", str(config), "--embedded-sim", "--duration", str(duration_s),
         "--no-figures", "--out", str(out / name)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "RUST_LOG": "warn,slam_node=info", "NO_COLOR": "1"},
    )
    lock = threading.Lock()
    samples, stderr = [], []
    endpoint = None
    deadline = time.monotonic() + 60
    for line in proc.stderr:
        stderr.append(line)
        m = "Zenoh session open" in line and re.search(r"(tcp/127\.0\.0\.1:\d+)", line)
        if m:
            endpoint = m.group(1)
            break
        if time.monotonic() > deadline:
            break
    session = subscriber = None
    tokens = []
    if endpoint:
        conf = zenoh.Config()
        conf.insert_json5("mode", '"peer"')
        conf.insert_json5("connect/endpoints", f'["{endpoint}"]')
        conf.insert_json5("listen/endpoints", "[]")
        conf.insert_json5("scouting/multicast/enabled", "false")
        session = zenoh.open(conf)

        def on_sample(sample):
            attachment = sample.attachment.to_bytes() if sample.attachment is not None else None
            with lock:
                samples.append((str(sample.key_expr), str(sample.encoding),
                                bytes(sample.payload.to_bytes()), attachment))

        subscriber = session.declare_subscriber("**", on_sample)
    threading.Thread(target=lambda: stderr.extend(proc.stderr), daemon=True).start()
    if session is not None and convention == "rmw_zenoh":
        time.sleep(1.0)
        for reply in session.liveliness().get("@ros2_lv/**", timeout=3.0):
            if reply.ok is not None:
                tokens.append(str(reply.ok.key_expr))
    try:
        proc.wait(timeout=300)
    except subprocess.TimeoutExpired:
        proc.kill()
    if subscriber is not None:
        subscriber.undeclare()
        session.close()
    with lock:
        got = list(samples)
    return proc.returncode, "".join(stderr)[-800:], got, tokens


def main():
    binary, out = Path(sys.argv[1]), Path(sys.argv[2])
    out.mkdir(parents=True, exist_ok=True)
    store = get_typestore(Stores.ROS2_HUMBLE)

    code, err, got, _ = run_daemon(binary, out, "run", "ros2dds", 16)
    check("the daemon ran (ros2dds)", code == 0, err if code else "")
    poses = [(e, p) for k, e, p, _ in got if k == "slam/odometry"]
    check("poses arrived on slam/odometry", len(poses) > 10, f"{len(poses)}")
    check("their encoding is application/cdr", all(e.startswith("application/cdr") for e, _ in poses))
    trajectory = {}
    for line in (out / "run" / "trajectory.tum").read_text().splitlines():
        if line and not line.startswith("#"):
            t, x, y = (float(v) for v in line.split()[:3])
            trajectory[round(t * 1e6)] = (x, y)
    decoded = matched = 0
    for _, payload in poses:
        msg = store.deserialize_cdr(payload, "nav_msgs/msg/Odometry")
        decoded += msg.header.frame_id == "map" and msg.child_frame_id == "base_link"
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        line = trajectory.get(round(t * 1e6))
        if line is not None:
            p = msg.pose.pose.position
            matched += abs(p.x - line[0]) <= 2e-6 and abs(p.y - line[1]) <= 2e-6
    check("rosbags decodes every pose as nav_msgs/msg/Odometry in map", decoded == len(poses), f"{decoded}")
    check("every pose received is the trajectory's line at its time", matched == len(poses), f"{matched} of {len(poses)}")
    tf = [p for k, _, p, _ in got if k == "tf"]
    clouds = [p for k, _, p, _ in got if k == "slam/map"]
    ok = bool(tf) and bool(clouds)
    for p in tf:
        ok &= len(store.deserialize_cdr(p, "tf2_msgs/msg/TFMessage").transforms) == 1
    for p in clouds:
        c = store.deserialize_cdr(p, "sensor_msgs/msg/PointCloud2")
        ok &= len(c.data) == c.row_step * c.height and [f.name for f in c.fields][:2] == ["x", "y"]
    check("tf and the map decode as TFMessage and PointCloud2", ok, f"{len(tf)} tf, {len(clouds)} maps")

    code, err, got, tokens = run_daemon(binary, out, "rmw", "rmw_zenoh", 8)
    check("the daemon ran (rmw_zenoh)", code == 0, err if code else "")
    expected = {
        f"0/{topic}/{ros.replace('/msg/', '::msg::dds_::')}_/{store.hash_rihs01(ros)}": ros
        for topic, ros in TYPES.items()
    }
    keys = {k for k, _, _, _ in got}
    check("every rmw_zenoh key carries the type hash rosbags computes", bool(keys) and keys <= set(expected),
          f"unexpected: {sorted(keys - set(expected))}")
    check("the pose, tf and detections keys were all seen",
          {k for k, r in expected.items() if not k.startswith(("0/tf_static", "0/slam/map"))} <= keys,
          f"{sorted(keys)}")
    bad = 0
    for k, _, payload, attachment in got:
        store.deserialize_cdr(payload, expected[k]) if k in expected else None
        bad += attachment is None or len(attachment) != 33 or attachment[16] != 16
    check("every rmw_zenoh sample decodes and carries the 33-byte attachment", bad == 0 and bool(got),
          f"{bad} of {len(got)} without")
    check("the node's liveliness token is in the graph",
          any(t.startswith("@ros2_lv/0/") and t.endswith("/NN/%/%/slam_node") for t in tokens), f"{tokens[:3]}")
    check("the pose publisher's token names the topic, type and hash",
          any("/MP/%/%/slam_node/%slam%odometry/nav_msgs::msg::dds_::Odometry_/"
              + store.hash_rihs01("nav_msgs/msg/Odometry") in t for t in tokens))

    finish()


if __name__ == "__main__":
    main()
