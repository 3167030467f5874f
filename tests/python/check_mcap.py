#!/usr/bin/env python3
"""Reads a slam-node MCAP recording with readers we did not write and checks it.

    python3 tests/python/check_mcap.py out/run.mcap out/trajectory.tum

1. `mcap` (+ `mcap-ros2-support`): profile `ros2`, every schema `ros2msg`, every channel
   `cdr`, every topic the daemon writes present; every message of every topic decoded, the
   counts equal to the summary's statistics.
2. `rosbags` (AnyReader with an empty type store: the types come from the file's own
   schemas): every message decoded again, the same counts.
3. Contents: each `/slam/odometry` pose equals the TUM trajectory's line (same count, time
   to 1 us, x and y to 2e-6 m as TUM prints 6 decimals, heading to 1e-6 rad), `/tf` carries
   the same transform, covariances are symmetric with non-negative diagonals, point clouds
   hold the fields named and `width * point_step` bytes, B-scans one encoder value and one
   timestamp per row.
4. A crash: the file cut at 60% of its length still gives every message of the chunks
   before the cut to `mcap`'s non-seeking reader.

Prints one line per check and `N passed, M failed`; exits 1 on any failure.
"""

import io
import math
import sys
import tempfile
from collections import Counter
from pathlib import Path

from mcap.exceptions import McapError
from mcap.reader import NonSeekingReader, make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

TOPICS = {
    "/radar_data/b_scan_msg": "navtech_msgs/msg/RadarBScanMsg",
    "/radar_data/configuration_data": "navtech_msgs/msg/RadarConfigurationMsg",
    "/odom/twist": "geometry_msgs/msg/TwistStamped",
    "/slam/odometry": "nav_msgs/msg/Odometry",
    "/tf": "tf2_msgs/msg/TFMessage",
    "/tf_static": "tf2_msgs/msg/TFMessage",
    "/slam/map": "sensor_msgs/msg/PointCloud2",
    "/slam/map_covariance": "visualization_msgs/msg/MarkerArray",
    "/slam/detections": "sensor_msgs/msg/PointCloud2",
}
CLOUD_FIELDS = {
    "/slam/map": ["x", "y", "z", "reflectivity", "absorption"],
    "/slam/detections": ["x", "y", "z", "power_db"],
}

from checklist import check, finish  # noqa: E402


def stamp_s(stamp):
    return stamp.sec + stamp.nanosec * 1e-9


def yaw(q):
    return 2.0 * math.atan2(q.z, q.w)


def wrap(a):
    return math.atan2(math.sin(a), math.cos(a))


def read_tum(path):
    poses = []
    for line in Path(path).read_text().splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        t, x, y, _z, _qx, _qy, qz, qw = (float(v) for v in line.split())
        poses.append((t, x, y, 2.0 * math.atan2(qz, qw)))
    return poses


def with_mcap(path):
    """Summary checks and every message decoded by mcap-ros2-support."""
    decoded = {}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        header = reader.get_header()
        summary = reader.get_summary()
        check("mcap: profile is ros2", header.profile == "ros2", repr(header.profile))
        encodings = {s.encoding for s in summary.schemas.values()}
        check("mcap: every schema is ros2msg", encodings == {"ros2msg"}, str(encodings))
        msg_encodings = {c.message_encoding for c in summary.channels.values()}
        check("mcap: every channel is cdr", msg_encodings == {"cdr"}, str(msg_encodings))
        found = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
        missing = {t: ty for t, ty in TOPICS.items() if found.get(t) != ty}
        check("mcap: every topic with its type", not missing, f"missing or mistyped {missing}")
        counts = Counter()
        for _schema, channel, _message, msg in reader.iter_decoded_messages():
            counts[channel.topic] += 1
            decoded.setdefault(channel.topic, []).append(msg)
        expected = {
            summary.channels[cid].topic: n
            for cid, n in summary.statistics.channel_message_counts.items()
        }
        check(
            "mcap-ros2-support: every message of every topic decoded",
            dict(counts) == expected,
            f"{sum(counts.values())} messages: {dict(sorted(counts.items()))}",
        )
        empty = [t for t in TOPICS if counts[t] == 0]
        check("mcap: every topic has messages", not empty, f"empty: {empty}")
    return decoded, counts


def with_rosbags(path, counts):
    """Every message decoded by rosbags from the file's own schemas."""
    seen = Counter()
    poses = []
    store = get_typestore(Stores.EMPTY)
    with AnyReader([Path(path)], default_typestore=store) as reader:
        for conn, _t, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            seen[conn.topic] += 1
            if conn.topic == "/slam/odometry":
                poses.append(msg)
    check(
        "rosbags: every message of every topic decoded, same counts",
        seen == counts,
        f"{sum(seen.values())} messages",
    )
    return poses


def contents(decoded, rosbags_poses, tum):
    odom = decoded.get("/slam/odometry", [])
    check("poses: one per TUM line", len(odom) == len(tum), f"{len(odom)} vs {len(tum)}")
    worst = [0.0, 0.0, 0.0]
    for msg, (t, x, y, th) in zip(odom, tum):
        p = msg.pose.pose
        worst[0] = max(worst[0], abs(stamp_s(msg.header.stamp) - t))
        worst[1] = max(worst[1], abs(p.position.x - x), abs(p.position.y - y))
        worst[2] = max(worst[2], abs(wrap(yaw(p.orientation) - th)))
    check(
        "poses: equal to the TUM trajectory",
        worst[0] < 1e-6 and worst[1] < 2e-6 and worst[2] < 1e-6,
        f"worst |dt| {worst[0]:.2e} s, |dxy| {worst[1]:.2e} m, |dyaw| {worst[2]:.2e} rad",
    )
    same = all(
        a.pose.pose.position.x == b.pose.pose.position.x
        and a.pose.pose.position.y == b.pose.pose.position.y
        and a.pose.covariance.tolist() == list(b.pose.covariance)
        for a, b in zip(rosbags_poses, odom)
    ) and len(rosbags_poses) == len(odom)
    check("poses: rosbags and mcap-ros2-support read the same values", same)
    bad_cov = 0
    for msg in odom:
        c = list(msg.pose.covariance)
        sym = all(abs(c[6 * r + k] - c[6 * k + r]) <= 1e-12 for r in range(6) for k in range(6))
        if not sym or any(c[7 * i] < 0 for i in range(6)):
            bad_cov += 1
    check("poses: covariances symmetric, diagonals >= 0", bad_cov == 0, f"{bad_cov} bad")
    tf = decoded.get("/tf", [])
    tf_ok = len(tf) == len(odom) and all(
        m.transforms[0].header.frame_id == "map"
        and m.transforms[0].child_frame_id == "base_link"
        and m.transforms[0].transform.translation.x == o.pose.pose.position.x
        and m.transforms[0].transform.translation.y == o.pose.pose.position.y
        for m, o in zip(tf, odom)
    )
    check("tf: map to base_link at every pose", tf_ok)
    for topic, names in CLOUD_FIELDS.items():
        clouds = decoded.get(topic, [])
        ok = bool(clouds) and all(
            [f.name for f in c.fields] == names
            and len(c.data) == c.width * c.height * c.point_step
            for c in clouds
        )
        points = sum(c.width for c in clouds)
        check(f"{topic}: fields {names}, data sized", ok, f"{len(clouds)} clouds, {points} points")
    markers = decoded.get("/slam/map_covariance", [])
    maps = decoded.get("/slam/map", [])
    ok = len(markers) == len(maps) and all(
        len(a.markers) == b.width + 1 for a, b in zip(markers, maps)
    )
    check("map covariance: a DELETEALL and one ellipse per mapped feature", ok)
    scans = decoded.get("/radar_data/b_scan_msg", [])
    ok = bool(scans) and all(
        len(s.b_scan_img.data) == s.b_scan_img.height * s.b_scan_img.step
        and len(s.encoder_values) == s.b_scan_img.height == len(s.timestamps)
        for s in scans
    )
    rows = sum(sum(1 for t in s.timestamps if t) for s in scans)
    check("b-scans: a row, an encoder value and a timestamp per azimuth", ok, f"{len(scans)} rotations, {rows} azimuths")


def truncated(path, counts):
    """The file cut at 60%: the non-seeking reader yields the complete chunks before it
    (in file order: ordering by log time would wait for the end)."""
    data = Path(path).read_bytes()
    cut = data[: int(len(data) * 0.6)]
    got = 0
    error = None
    try:
        reader = NonSeekingReader(io.BytesIO(cut), decoder_factories=[DecoderFactory()])
        for _s, _c, _m, _msg in reader.iter_decoded_messages(log_time_order=False):
            got += 1
    except (McapError, EOFError, ValueError) as e:
        error = type(e).__name__
    total = sum(counts.values())
    check(
        "crash: a file cut at 60% still reads up to its last complete chunk",
        0 < got < total,
        f"{got} of {total} messages before {error or 'the end'}",
    )


def main():
    if len(sys.argv) != 3:
        print(__doc__)
        return 2
    path, tum_path = sys.argv[1], sys.argv[2]
    decoded, counts = with_mcap(path)
    rosbags_poses = with_rosbags(path, counts)
    contents(decoded, rosbags_poses, read_tum(tum_path))
    truncated(path, counts)
    finish()


if __name__ == "__main__":
    sys.exit(main())
