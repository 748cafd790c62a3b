#!/usr/bin/env python3
"""Converts a CARMEN log (ROBOTLASER1 or FLASER lines; .gz is fine) to a ROS 2 bag, written by
the `rosbags` package: MCAP storage by default (sqlite3 with --storage sqlite3), CDR; or, with
--storage rosbag1, to a ROS 1 bag (OUT is the .bag file; --compression none, bz2 or lz4).

Topics:
  /scan   sensor_msgs/msg/LaserScan, frame `laser`, stamped with the log's time;
  /truth  geometry_msgs/msg/PoseStamped, frame `map`: the laser pose the line carries (the
          corrected pose of a SLAM-corrected log), unless the log says its poses are not
          ground truth;
  /odom   nav_msgs/msg/Odometry, frame `odom`: a FLASER line's odometry pose, a ROBOTLASER1
          line's robot pose (gema2 reads both as odometry);
          with --odom-on-tf, that pose on /tf instead (tf2_msgs/msg/TFMessage, odom ->
          base_link), as robots that publish odometry only on /tf leave it.

The scans are read as gema2 reads them (docs/sensors.md): a FLASER line's n readings start at
-90 degrees and span 180 (pi/n apart for 180 or 360 readings, pi/(n-1) otherwise), unless
--flaser-fov / --flaser-start say otherwise; readings at or beyond the maximum range (50 m for
FLASER unless --flaser-range-max) are written +inf, "no return" in REP 117.

Usage: carmen2bag.py LOG OUT [--storage mcap|sqlite3|rosbag1] [--compression none|bz2|lz4]
       [--flaser-fov DEG] [--flaser-start DEG] [--flaser-range-max M] [--odom-on-tf]
Run it with the project's Python: `$(scripts/python-env) scripts/carmen2bag.py ...`.
"""

import argparse
import gzip
import math
import sys
from pathlib import Path

import numpy as np
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

NO_TRUTH_MARKER = "# gema2: poses are not ground truth"
MIN_VALID_RANGE = 0.02


def open_log(path):
    raw = open(path, "rb")
    if raw.read(2) == b"\x1f\x8b":
        raw.seek(0)
        return gzip.open(raw, "rt", encoding="utf-8", errors="replace")
    raw.seek(0)
    return open(path, "rt", encoding="utf-8", errors="replace")


def flaser(t, args):
    """A FLASER line's scan: (start, increment, range_max, ranges, laser pose, odometry pose, stamp)."""
    n = int(t[1])
    if n < 2:
        raise ValueError("fewer than two readings")
    ranges = [float(v) for v in t[2 : 2 + n]]
    rest = t[2 + n :]
    laser = tuple(float(v) for v in rest[0:3])
    odom = tuple(float(v) for v in rest[3:6]) if len(rest) >= 6 else None
    stamp = float(rest[6]) if len(rest) >= 7 else math.nan
    if args.flaser_fov is not None:
        fov = math.radians(args.flaser_fov)
        start = -fov / 2
        inc = fov / (n - 1)
    else:
        start = -math.pi / 2
        inc = math.pi / n if n in (180, 360) else math.pi / (n - 1)
    if args.flaser_start is not None:
        start = math.radians(args.flaser_start)
    return start, inc, args.flaser_range_max, ranges, laser, odom, stamp


def robotlaser1(t):
    """A ROBOTLASER1 line's scan, with or without the laser_type field: (start, increment,
    range_max, ranges, laser pose, robot pose, stamp)."""

    def fits(k):
        try:
            n = int(t[k])
            m = int(t[k + 1 + n])
        except (ValueError, IndexError):
            return False
        return len(t) >= k + 2 + n + m + 6

    if len(t) > 8 and t[1].isdigit() and fits(8):
        b = 2
    elif fits(7):
        b = 1
    else:
        raise ValueError("the reading and remission counts do not match the line's length")
    start, fov, res, max_range = (float(v) for v in t[b : b + 4])
    n = int(t[b + 6])
    ranges = [float(v) for v in t[b + 7 : b + 7 + n]]
    m = int(t[b + 7 + n])
    p = b + 8 + n + m
    laser = tuple(float(v) for v in t[p : p + 3])
    robot = tuple(float(v) for v in t[p + 3 : p + 6]) if len(t) >= p + 6 else None
    inc = res if res != 0.0 else (fov / (n - 1) if n > 1 else 0.0)
    stamp = float(t[p + 11]) if len(t) > p + 11 else math.nan
    return start, inc, max_range, ranges, laser, robot, stamp


def stamp_of(seconds):
    sec = math.floor(seconds)
    nanosec = min(int(round((seconds - sec) * 1e9)), 999_999_999)
    return int(sec), nanosec


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("log")
    ap.add_argument("out", help="the bag directory to create")
    ap.add_argument("--storage", choices=["mcap", "sqlite3", "rosbag1"], default="mcap")
    ap.add_argument("--compression", choices=["none", "bz2", "lz4"], default="none")
    ap.add_argument("--flaser-fov", type=float)
    ap.add_argument("--flaser-start", type=float)
    ap.add_argument("--flaser-range-max", type=float, default=50.0)
    ap.add_argument("--odom-on-tf", action="store_true", help="the odometry on /tf (odom -> base_link), not /odom")
    args = ap.parse_args()

    ros1 = args.storage == "rosbag1"
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if "tf2_msgs/msg/TFMessage" not in ts.types:
        # rosbags' ROS 1 store lacks it; its definition is ROS 2's
        ts.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))
    serialize = ts.serialize_ros1 if ros1 else ts.serialize_cdr
    T = ts.types
    Time, Header = T["builtin_interfaces/msg/Time"], T["std_msgs/msg/Header"]
    LaserScan, PoseStamped = T["sensor_msgs/msg/LaserScan"], T["geometry_msgs/msg/PoseStamped"]
    Pose, Point, Quaternion = T["geometry_msgs/msg/Pose"], T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Quaternion"]
    Odometry, PoseWithCov = T["nav_msgs/msg/Odometry"], T["geometry_msgs/msg/PoseWithCovariance"]
    TwistWithCov, Twist, Vector3 = T["geometry_msgs/msg/TwistWithCovariance"], T["geometry_msgs/msg/Twist"], T["geometry_msgs/msg/Vector3"]
    TFMessage, TransformStamped, Transform = T["tf2_msgs/msg/TFMessage"], T["geometry_msgs/msg/TransformStamped"], T["geometry_msgs/msg/Transform"]

    seq = 0

    def header(sec, nanosec, frame):
        nonlocal seq
        seq += 1
        stamp = Time(sec=sec, nanosec=nanosec)
        return Header(seq=seq, stamp=stamp, frame_id=frame) if ros1 else Header(stamp=stamp, frame_id=frame)

    def pose(x, y, th):
        return Pose(position=Point(x=x, y=y, z=0.0), orientation=Quaternion(x=0.0, y=0.0, z=math.sin(th / 2), w=math.cos(th / 2)))

    if ros1:
        writer = Writer1(Path(args.out))
        if args.compression != "none":
            writer.set_compression(Writer1.CompressionFormat[args.compression.upper()])
    else:
        storage = StoragePlugin.MCAP if args.storage == "mcap" else StoragePlugin.SQLITE3
        writer = Writer(Path(args.out), version=8, storage_plugin=storage)
    truth = True
    scans = skipped = replaced = 0
    last_time = 0
    last_good = 0.0
    with writer as w:
        scan_c = w.add_connection("/scan", LaserScan.__msgtype__, typestore=ts)
        truth_c = w.add_connection("/truth", PoseStamped.__msgtype__, typestore=ts)
        if args.odom_on_tf:
            odom_c = w.add_connection("/tf", TFMessage.__msgtype__, typestore=ts)
        else:
            odom_c = w.add_connection("/odom", Odometry.__msgtype__, typestore=ts)
        with open_log(args.log) as f:
            for number, line in enumerate(f, 1):
                if line.startswith(NO_TRUTH_MARKER):
                    truth = False
                t = line.split()
                if not t or t[0] not in ("FLASER", "ROBOTLASER1"):
                    continue
                try:
                    start, inc, max_range, ranges, laser, odom, stamp = flaser(t, args) if t[0] == "FLASER" else robotlaser1(t)
                except (ValueError, IndexError) as e:
                    print(f"{args.log}:{number}: skipped: {e}", file=sys.stderr)
                    skipped += 1
                    continue
                # a stamp ROS cannot carry (int32 seconds, none before 1970; the MIT log has
                # wrapped ones) is replaced by the last good one: the scan still gets its truth
                if not (math.isfinite(stamp) and 0 <= stamp < 2**31):
                    stamp = last_good
                    replaced += 1
                last_good = stamp
                sec, nanosec = stamp_of(stamp)
                # the bag's receive time must not go back; the header keeps the log's time
                log_time = max(sec * 1_000_000_000 + nanosec, last_time)
                last_time = log_time
                r = np.array([math.inf if v >= max_range * (1 - 1e-6) else v for v in ranges], dtype=np.float32)
                msg = LaserScan(
                    header=header(sec, nanosec, "laser"),
                    angle_min=start,
                    angle_max=start + inc * (len(ranges) - 1),
                    angle_increment=inc,
                    time_increment=0.0,
                    scan_time=0.0,
                    range_min=MIN_VALID_RANGE,
                    range_max=max_range,
                    ranges=r,
                    intensities=np.array([], dtype=np.float32),
                )
                w.write(scan_c, log_time, serialize(msg, LaserScan.__msgtype__))
                if truth:
                    p = PoseStamped(header=header(sec, nanosec, "map"), pose=pose(*laser))
                    w.write(truth_c, log_time, serialize(p, PoseStamped.__msgtype__))
                if odom is not None and args.odom_on_tf:
                    p = pose(*odom)
                    moved = Transform(
                        translation=Vector3(x=p.position.x, y=p.position.y, z=0.0), rotation=p.orientation
                    )
                    tf = TFMessage(
                        transforms=[TransformStamped(header=header(sec, nanosec, "odom"), child_frame_id="base_link", transform=moved)]
                    )
                    w.write(odom_c, log_time, serialize(tf, TFMessage.__msgtype__))
                elif odom is not None:
                    o = Odometry(
                        header=header(sec, nanosec, "odom"),
                        child_frame_id="base_link",
                        pose=PoseWithCov(pose=pose(*odom), covariance=np.zeros(36)),
                        twist=TwistWithCov(twist=Twist(linear=Vector3(x=0.0, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=0.0)), covariance=np.zeros(36)),
                    )
                    w.write(odom_c, log_time, serialize(o, Odometry.__msgtype__))
                scans += 1
    print(
        f"{args.out}: {scans} scans{'' if truth else ', no truth'}; {skipped} lines skipped; "
        f"{replaced} stamps out of ROS's range replaced by the one before",
        file=sys.stderr,
    )


if __name__ == "__main__":
    main()
