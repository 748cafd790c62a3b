#!/usr/bin/env python3
"""A ROS 2 robot as DDS sees it, played by Eclipse Cyclone DDS (PyPI `cyclonedds`), to test
gema2's ros2 bridge against an implementation that is not ours.

It publishes, as ROS 2 does:
  rt/scan        sensor_msgs::msg::dds_::LaserScan_ (best effort), the scans of a CARMEN log
                 (ROBOTLASER1 lines, e.g. from `gema2 sim`) at --rate, stamped 0.025 s apart;
  rt/tf_static   tf2_msgs::msg::dds_::TFMessage_ (reliable, transient local): base_link ->
                 laser at --laser-pose; with --upside-down, the laser rolled 180 degrees there,
                 its scans read as such a laser reads them (the span mirrored, the ranges in
                 reverse);
  rt/odom        with --odom, nav_msgs::msg::dds_::Odometry_ (reliable): each line's robot pose
                 (ROBOTLASER1's odometry), stamped as its scan and written just before it;
  rt/tf          with --odom-on-tf instead, that pose as tf2_msgs::msg::dds_::TFMessage_
                 (reliable), as robots that publish odometry only on /tf do: odom ->
                 base_footprint, beside a localizer's map -> odom; /tf_static then hangs base_link
                 from base_footprint;
and, with --grid, a map_server map (YAML and PGM) on rt/map as nav_msgs::msg::dds_::OccupancyGrid_
(reliable, transient local), as a ROS 2 map_server does; and subscribes to rt/gema2/pose and
rt/initialpose (PoseWithCovarianceStamped, reliable).

Prints one CSV line a pose received: topic, scan number, x, y, yaw, the x, y and yaw variances,
and the latency from publishing the scan to receiving its pose (ms); then, on stderr, the
latency's p50 and p99. Run every DDS participant of a test in a network namespace (the test
does): discovery multicasts.

With --hostile N, every N-th scan (scan numbers N-1, 2N-1, ...) is sent damaged instead, as a
faulty driver or a hostile peer might: a layout of NaN, zero or infinite numbers, readings all
NaN, infinite or huge, no readings, 200 000 readings, or bounds the wrong way round, in turn
(`HOSTILE`). Its stamp is kept, so a pose for it still names its scan.

Usage: ros2_peer.py LOG [--rate HZ] [--laser-pose x,y,yaw] [--upside-down] [--grid MAP.yaml]
       [--odom | --odom-on-tf] [--hostile N] [--wait S] [--domain N]
"""

import argparse
import math
import sys
import threading
import time
from dataclasses import dataclass

from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import array, float32, float64, int8, int32, sequence, uint32
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration


@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32
    nanosec: uint32


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time
    frame_id: str


@dataclass
class LaserScan(IdlStruct, typename="sensor_msgs::msg::dds_::LaserScan_"):
    header: Header
    angle_min: float32
    angle_max: float32
    angle_increment: float32
    time_increment: float32
    scan_time: float32
    range_min: float32
    range_max: float32
    ranges: sequence[float32]
    intensities: sequence[float32]


@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: float64
    y: float64
    z: float64


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64
    y: float64
    z: float64


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: float64
    y: float64
    z: float64
    w: float64


@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point
    orientation: Quaternion


@dataclass
class PoseWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovariance_"):
    pose: Pose
    covariance: array[float64, 36]


@dataclass
class PoseWithCovarianceStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovarianceStamped_"):
    header: Header
    pose: PoseWithCovariance


@dataclass
class Twist(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    linear: Vector3
    angular: Vector3


@dataclass
class TwistWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::TwistWithCovariance_"):
    twist: Twist
    covariance: array[float64, 36]


@dataclass
class Odometry(IdlStruct, typename="nav_msgs::msg::dds_::Odometry_"):
    header: Header
    child_frame_id: str
    pose: PoseWithCovariance
    twist: TwistWithCovariance


@dataclass
class MapMetaData(IdlStruct, typename="nav_msgs::msg::dds_::MapMetaData_"):
    map_load_time: Time
    resolution: float32
    width: uint32
    height: uint32
    origin: Pose


@dataclass
class OccupancyGrid(IdlStruct, typename="nav_msgs::msg::dds_::OccupancyGrid_"):
    header: Header
    info: MapMetaData
    data: sequence[int8]


@dataclass
class Transform(IdlStruct, typename="geometry_msgs::msg::dds_::Transform_"):
    translation: Vector3
    rotation: Quaternion


@dataclass
class TransformStamped(IdlStruct, typename="geometry_msgs::msg::dds_::TransformStamped_"):
    header: Header
    child_frame_id: str
    transform: Transform


@dataclass
class TFMessage(IdlStruct, typename="tf2_msgs::msg::dds_::TFMessage_"):
    transforms: sequence[TransformStamped]


# what ROS 2's rmw_cyclonedds puts on the wire: XCDR1
CDR = Policy.DataRepresentation(use_cdrv0_representation=True)
SENSOR = Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(5), CDR)
RELIABLE = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepLast(100), CDR)
LATCHED = Qos(
    Policy.Reliability.Reliable(duration(milliseconds=100)),
    Policy.Durability.TransientLocal,
    Policy.History.KeepLast(1),
    CDR,
)
START = 1000.0  # the first scan's stamp, seconds
STEP = 0.025  # between stamps


def scans_of(log):
    """(start, increment, range_max, ranges, robot pose) of each ROBOTLASER1 line."""
    sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
    from carmen2bag import robotlaser1  # the converter's parser: one reading of the format

    out = []
    for line in open(log):
        t = line.split()
        if t and t[0] == "ROBOTLASER1":
            start, inc, max_range, ranges, _, robot, _ = robotlaser1(t)
            out.append((start, inc, max_range, ranges, robot))
    return out


def grid_of(yaml_path):
    """The OccupancyGrid a ROS map_server publishes for a YAML map (trinary, as its defaults)."""
    from pathlib import Path

    meta = {}
    for line in open(yaml_path):
        if ":" in line and not line.lstrip().startswith("#"):
            k, v = line.split(":", 1)
            meta[k.strip()] = v.strip()
    image = Path(yaml_path).parent / meta["image"].strip("'\"")
    raw = open(image, "rb").read()
    tokens, pos = [], 0
    while len(tokens) < 4:  # magic, width, height, maxval; comments skipped
        while raw[pos : pos + 1].isspace():
            pos += 1
        if raw[pos : pos + 1] == b"#":
            pos = raw.index(b"\n", pos)
            continue
        end = pos
        while not raw[end : end + 1].isspace():
            end += 1
        tokens.append(raw[pos:end].decode())
        pos = end
    pos += 1
    assert tokens[0] == "P5", "a binary PGM"
    width, height, maxval = int(tokens[1]), int(tokens[2]), int(tokens[3])
    pixels = raw[pos : pos + width * height]
    occupied, free = float(meta.get("occupied_thresh", 0.65)), float(meta.get("free_thresh", 0.196))
    negate = meta.get("negate", "0").strip() not in ("0", "false")
    data = []
    for row in range(height - 1, -1, -1):  # the image's top row is the grid's last
        for v in pixels[row * width : (row + 1) * width]:
            p = v / maxval if negate else (maxval - v) / maxval
            data.append(100 if p > occupied else 0 if p < free else -1)
    origin = [float(x) for x in meta["origin"].strip("[]").split(",")]
    return OccupancyGrid(
        header=Header(stamp=Time(sec=0, nanosec=0), frame_id="map"),
        info=MapMetaData(
            map_load_time=Time(sec=0, nanosec=0),
            resolution=float(meta["resolution"]),
            width=width,
            height=height,
            origin=Pose(position=Point(x=origin[0], y=origin[1], z=0.0), orientation=quaternion(origin[2])),
        ),
        data=data,
    )


def _set(msg, **fields):
    for name, value in fields.items():
        setattr(msg, name, value)
    return msg


# the damages --hostile makes, in turn: each takes a good LaserScan and returns it damaged
HOSTILE = [
    lambda m: _set(m, angle_increment=math.nan),
    lambda m: _set(m, angle_increment=0.0),
    lambda m: _set(m, angle_min=math.inf, angle_max=-math.inf),
    lambda m: _set(m, range_max=math.inf, ranges=[math.inf] * len(m.ranges)),
    lambda m: _set(m, range_min=-math.inf, ranges=[-math.inf] * len(m.ranges)),
    lambda m: _set(m, ranges=[math.nan] * len(m.ranges)),
    lambda m: _set(m, ranges=[(1e30 if j % 2 else -1e30) for j in range(len(m.ranges))]),
    lambda m: _set(m, ranges=[]),
    lambda m: _set(m, ranges=[1.0] * 200_000),
    lambda m: _set(m, range_min=m.range_max, range_max=m.range_min),
    lambda m: _set(m, angle_increment=-10.0),
    lambda m: _set(m, intensities=[math.nan] * (3 * len(m.ranges))),
]


def quaternion(yaw, roll=0.0):
    # Rz(yaw) Rx(roll)
    cy, sy, cr, sr = math.cos(yaw / 2), math.sin(yaw / 2), math.cos(roll / 2), math.sin(roll / 2)
    return Quaternion(x=cy * sr, y=sy * sr, z=sy * cr, w=cy * cr)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("log")
    ap.add_argument("--rate", type=float, default=40.0)
    ap.add_argument("--laser-pose", default="0,0,0")
    ap.add_argument("--wait", type=float, default=5.0, help="seconds to wait for poses after the last scan")
    ap.add_argument("--discovery", type=float, default=20.0, help="seconds to wait for the bridge to appear")
    ap.add_argument("--domain", type=int, default=0)
    ap.add_argument("--grid", help="a map_server YAML map to publish on rt/map")
    ap.add_argument("--regrid-after", type=int, help="publish the grid again after this many scans (a map update)")
    odom = ap.add_mutually_exclusive_group()
    odom.add_argument("--odom", action="store_true", help="publish each line's robot pose on rt/odom")
    odom.add_argument("--odom-on-tf", action="store_true", help="publish it on rt/tf, odom -> base_footprint")
    ap.add_argument("--upside-down", action="store_true", help="the laser is mounted rolled 180 degrees")
    ap.add_argument("--hostile", type=int, help="send every N-th scan damaged (HOSTILE, in turn)")
    args = ap.parse_args()
    mount = [float(v) for v in args.laser_pose.split(",")]
    scans = scans_of(args.log)

    dp = DomainParticipant(args.domain)
    scan_w = DataWriter(dp, Topic(dp, "rt/scan", LaserScan), qos=SENSOR)
    odom_w = DataWriter(dp, Topic(dp, "rt/odom", Odometry), qos=RELIABLE) if args.odom else None
    if args.odom_on_tf:
        odom_w = DataWriter(dp, Topic(dp, "rt/tf", TFMessage), qos=RELIABLE)
    tf_w = DataWriter(dp, Topic(dp, "rt/tf_static", TFMessage), qos=LATCHED)
    if args.grid:
        map_w = DataWriter(dp, Topic(dp, "rt/map", OccupancyGrid), qos=LATCHED)
        grid = grid_of(args.grid)
        map_w.write(grid)
    readers = {
        name: DataReader(dp, Topic(dp, f"rt/{name}", PoseWithCovarianceStamped), qos=RELIABLE)
        for name in ("gema2/pose", "initialpose")
    }
    def transform(at, parent, child, x, y, z, rotation):
        return TransformStamped(
            header=Header(stamp=at, frame_id=parent),
            child_frame_id=child,
            transform=Transform(translation=Vector3(x=x, y=y, z=z), rotation=rotation),
        )

    fixed = [
        transform(
            Time(sec=0, nanosec=0), "base_link", "laser", mount[0], mount[1], 0.3,
            quaternion(mount[2], math.pi if args.upside_down else 0.0),
        )
    ]
    if args.odom_on_tf:
        fixed.append(transform(Time(sec=0, nanosec=0), "base_footprint", "base_link", 0.0, 0.0, 0.1, quaternion(0.0)))
    tf_w.write(TFMessage(transforms=fixed))
    # the bridge's scan reader and pose writer must be found before the first scan
    deadline = time.monotonic() + args.discovery
    while not (
        scan_w.get_matched_subscriptions()
        and readers["gema2/pose"].get_matched_publications()
        and (odom_w is None or odom_w.get_matched_subscriptions())
    ):
        if time.monotonic() > deadline:
            sys.exit("no gema2 bridge found on DDS")
        time.sleep(0.05)
    time.sleep(0.5)

    sent = {}  # scan number -> monotonic publish time
    received = []  # (topic, k, pose, latency)
    done = threading.Event()

    def collect():
        while not done.is_set():
            got = False
            for name, r in readers.items():
                for m in r.take(N=64):
                    if not isinstance(m, PoseWithCovarianceStamped):
                        continue  # a writer's dispose or unregister (the bridge stopping)
                    now = time.monotonic()
                    s = m.header.stamp
                    k = round((s.sec + s.nanosec * 1e-9 - START) / STEP)
                    q = m.pose.pose.orientation
                    yaw = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))
                    c = m.pose.covariance
                    p = m.pose.pose.position
                    latency = (now - sent[k]) * 1000 if k in sent else float("nan")
                    received.append((name, k, (p.x, p.y, yaw, c[0], c[7], c[35]), latency, m.header.frame_id))
                    got = True
            if not got:
                time.sleep(0.0002)

    collector = threading.Thread(target=collect)
    collector.start()
    period = 1.0 / args.rate
    t0 = time.monotonic()
    for k, (start, inc, max_range, ranges, robot) in enumerate(scans):
        if args.upside_down:
            # the rolled laser's beam j, at its angle a_j, looks where the upright one's beam at
            # -a_j does: its span is the upright one's mirrored, its ranges the upright ones in
            # reverse
            start = -(start + inc * (len(ranges) - 1))
            ranges = list(reversed(ranges))
        due = t0 + k * period
        while time.monotonic() < due:
            time.sleep(min(0.001, max(0.0, due - time.monotonic())))
        stamp = START + k * STEP
        sec = int(stamp)
        at = Time(sec=sec, nanosec=int(round((stamp - sec) * 1e9)))
        if args.odom_on_tf and robot is not None:
            x, y, yaw = robot
            odom_w.write(
                TFMessage(
                    transforms=[
                        transform(at, "map", "odom", 3.0, -1.0, 0.0, quaternion(0.7 + 0.01 * k)),
                        transform(at, "odom", "base_footprint", x, y, 0.0, quaternion(yaw)),
                    ]
                )
            )
        elif odom_w is not None and robot is not None:
            x, y, yaw = robot
            odom_w.write(
                Odometry(
                    header=Header(stamp=at, frame_id="odom"),
                    child_frame_id="base_link",
                    pose=PoseWithCovariance(
                        pose=Pose(position=Point(x=x, y=y, z=0.0), orientation=quaternion(yaw)), covariance=[0.0] * 36
                    ),
                    twist=TwistWithCovariance(
                        twist=Twist(linear=Vector3(x=0.0, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=0.0)),
                        covariance=[0.0] * 36,
                    ),
                )
            )
        msg = LaserScan(
            header=Header(stamp=at, frame_id="laser"),
            angle_min=start,
            angle_max=start + inc * (len(ranges) - 1),
            angle_increment=inc,
            time_increment=0.0,
            scan_time=period,
            range_min=0.02,
            range_max=max_range,
            ranges=[r if r < max_range else math.inf for r in ranges],
            intensities=[],
        )
        if args.hostile and k % args.hostile == args.hostile - 1:
            msg = HOSTILE[(k // args.hostile) % len(HOSTILE)](msg)
        sent[k] = time.monotonic()
        scan_w.write(msg)
        if args.grid and args.regrid_after == k + 1:
            grid.header.stamp = Time(sec=1, nanosec=0)
            map_w.write(grid)
    last = time.monotonic()
    while time.monotonic() - last < args.wait:
        n = len(received)
        time.sleep(0.2)
        if len(received) != n:
            last = time.monotonic()
    done.set()
    collector.join()
    for name, k, (x, y, yaw, cxx, cyy, ctt), latency, frame in sorted(received, key=lambda r: (r[0], r[1])):
        print(f"{name},{k},{x:.4f},{y:.4f},{yaw:.5f},{cxx:.6g},{cyy:.6g},{ctt:.6g},{latency:.3f},{frame}")
    lat = sorted(r[3] for r in received if r[0] == "gema2/pose" and not math.isnan(r[3]))
    if lat:
        p = lambda q: lat[min(len(lat) - 1, int(q * len(lat)))]
        print(f"scans sent {len(scans)}, poses {len(lat)}, latency p50 {p(0.5):.2f} ms p99 {p(0.99):.2f} ms", file=sys.stderr)
    else:
        print(f"scans sent {len(scans)}, no pose received", file=sys.stderr)


if __name__ == "__main__":
    main()
