#!/usr/bin/env python3
"""Receives slam-node's live pose over Zenoh with readers we did not write.

    python3 tests/python/check_zenoh.py path/to/slam-node OUT_DIR

The binary must be built with `--features zenoh`. A Python `eclipse-zenoh` peer listens on
a free 127.0.0.1 port (multicast scouting off, no router); the daemon runs against its
embedded simulator (`--embedded-sim --fast --duration 30`) with `[output.zenoh]` connecting
to that port.

1. Poses arrive on the key `slam/odometry` (zenoh-bridge-ros2dds's key for the ROS 2 topic
   `/slam/odometry`) with the encoding `application/cdr`.
2. `rosbags` decodes every payload as `nav_msgs/msg/Odometry` with its own ROS 2 type store
   (the 4-byte CDR header and all), frames `map` and `base_link`.
3. Each pose received is the TUM trajectory's line at its time (x, y to 2e-6 m).
4. `/tf` and `/slam/map` decode as `tf2_msgs/msg/TFMessage` and `sensor_msgs/msg/PointCloud2`.

Prints one line per check and `N passed, M failed`; exits 1 on any failure.
"""

import json
import socket
import subprocess
import sys
import threading
from pathlib import Path

import zenoh
from rosbags.typesys import Stores, get_typestore

results = []


def check(name, ok, detail=""):
    results.append(ok)
    print(f"{'ok  ' if ok else 'FAIL'} {name}{': ' + detail if detail else ''}")


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def open_session():
    for _ in range(5):
        endpoint = f"tcp/127.0.0.1:{free_port()}"
        conf = zenoh.Config()
        conf.insert_json5("mode", '"peer"')
        conf.insert_json5("listen/endpoints", json.dumps([endpoint]))
        conf.insert_json5("connect/endpoints", "[]")
        conf.insert_json5("scouting/multicast/enabled", "false")
        try:
            return zenoh.open(conf), endpoint
        except Exception:  # the port was taken meanwhile: another one
            continue
    raise SystemExit("no loopback port could be listened on")


def main():
    binary, out = Path(sys.argv[1]), Path(sys.argv[2])
    out.mkdir(parents=True, exist_ok=True)
    store = get_typestore(Stores.ROS2_HUMBLE)
    session, endpoint = open_session()
    lock = threading.Lock()
    samples = []

    def on_sample(sample):
        with lock:
            samples.append((str(sample.key_expr), str(sample.encoding), bytes(sample.payload.to_bytes())))

    subscriber = session.declare_subscriber("**", on_sample)
    config = out / "zenoh-check.toml"
    config.write_text(
        "[output]\npictures = false\nprogress = false\n\n[output.zenoh]\nenabled = true\n"
        f'connect = ["{endpoint}"]\nlisten = []\nmulticast_scouting = false\n'
    )
    run = subprocess.run(
        [str(binary), "--config", str(config), "--embedded-sim", "--fast", "--duration", "30",
         "--no-figures", "--out", str(out / "run")],
        capture_output=True, text=True, timeout=300,
    )
    check("the daemon ran", run.returncode == 0, run.stderr[-500:] if run.returncode else "")
    subscriber.undeclare()
    session.close()
    with lock:
        got = list(samples)

    poses = [(e, p) for k, e, p in got if k == "slam/odometry"]
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
    tf = [p for k, _, p in got if k == "tf"]
    clouds = [p for k, _, p in got if k == "slam/map"]
    ok = bool(tf) and bool(clouds)
    for p in tf:
        ok &= len(store.deserialize_cdr(p, "tf2_msgs/msg/TFMessage").transforms) == 1
    for p in clouds:
        c = store.deserialize_cdr(p, "sensor_msgs/msg/PointCloud2")
        ok &= len(c.data) == c.row_step * c.height and [f.name for f in c.fields][:2] == ["x", "y"]
    check("tf and the map decode as TFMessage and PointCloud2", ok, f"{len(tf)} tf, {len(clouds)} maps")

    failed = results.count(False)
    print(f"{len(results) - failed} passed, {failed} failed")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
