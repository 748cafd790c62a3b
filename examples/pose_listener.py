#!/usr/bin/env python3
"""Prints every pose gema2 publishes, read from shared memory with the `iceoryx2` Python
package (the same 0.10 release as the pipeline's crate): no copy, no Rust.

The payload is `gema2/pose`, mirrored below with ctypes field for field as the C struct
docs/design.md gives ("Payloads as C structs"). iceoryx2 refuses to open the service when the
name, size or alignment disagree, so a layout that drifted is an error, never misread memory.

Usage (with a pipeline running, e.g. `gema2 run`):
    $(scripts/python-env) examples/pose_listener.py [--prefix gema2] [--count N] [--idle S] [--timeout S]

Prints one line a pose: seq, status, x, y, theta (radians), cost, hypotheses, map version.
"""

import argparse
import ctypes
import sys
import time

import iceoryx2 as iox2

MAX_HYPOTHESES = 32
STAGES = 3
NAME_LEN = 32
STATUS = {0: "ok", 1: "ambiguous", 2: "failed"}


class StageSpan(ctypes.Structure):
    _fields_ = [("enter_ns", ctypes.c_uint64), ("leave_ns", ctypes.c_uint64)]


class Header(ctypes.Structure):
    _fields_ = [
        ("seq", ctypes.c_uint64),
        ("stamp_ns", ctypes.c_uint64),
        ("stages", StageSpan * STAGES),
        ("producer", ctypes.c_uint8 * NAME_LEN),
    ]


class PoseXyt(ctypes.Structure):
    _fields_ = [("x", ctypes.c_double), ("y", ctypes.c_double), ("theta", ctypes.c_double)]


class Hypothesis(ctypes.Structure):
    _fields_ = [
        ("pose", PoseXyt),
        ("cost", ctypes.c_double),
        ("inliers", ctypes.c_double),
        ("through", ctypes.c_double),
        ("scan_corner", ctypes.c_uint32),
        ("map_corner", ctypes.c_uint32),
    ]


class PoseMsg(ctypes.Structure):
    """`gema2/pose`: the ranked hypotheses of one scan."""

    _fields_ = [
        ("header", Header),
        ("status", ctypes.c_uint32),
        ("count", ctypes.c_uint32),
        ("candidates", ctypes.c_uint32),
        ("map_version", ctypes.c_uint32),
        ("has_truth", ctypes.c_uint32),
        ("_pad", ctypes.c_uint32),
        ("truth", PoseXyt),
        ("hypotheses", Hypothesis * MAX_HYPOTHESES),
    ]

    @staticmethod
    def type_name() -> str:
        """The name the Rust side gives the payload (`#[type_name]`)."""
        return "gema2::PoseMsg"


# the documented layout (messages/src/payload.rs tests the same numbers on the Rust side)
assert ctypes.sizeof(PoseMsg) == 1936 and PoseMsg.hypotheses.offset == 144


def open_service(node, name, deadline):
    """The pose topic's data and event services, waiting until the pipeline has made them."""
    while True:
        try:
            data = node.service_builder(iox2.ServiceName.new(name)).publish_subscribe(PoseMsg).open()
            event = node.service_builder(iox2.ServiceName.new(name)).event().open()
            return data, event
        except iox2.PublishSubscribeOpenError as e:
            if "DoesNotExist" not in repr(e) or time.monotonic() > deadline:
                sys.exit(f"{name}: {e!r}")
        except iox2.EventOpenError as e:
            if time.monotonic() > deadline:
                sys.exit(f"{name} (event): {e!r}")
        time.sleep(0.05)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--prefix", default="gema2", help="the pipeline's prefix (gema2 run --prefix)")
    ap.add_argument("--count", type=int, default=0, help="stop after this many poses (0: never)")
    ap.add_argument("--idle", type=float, default=0, help="stop when no pose came for this many seconds after one did (a replay ended)")
    ap.add_argument("--timeout", type=float, default=0, help="fail after this many seconds (0: never)")
    args = ap.parse_args()

    iox2.set_log_level_from_env_or(iox2.LogLevel.Warn)
    node = iox2.NodeBuilder.new().create(iox2.ServiceType.Ipc)
    deadline = time.monotonic() + (args.timeout or 1e9)
    data, event = open_service(node, f"{args.prefix}/pose", deadline)
    subscriber = data.subscriber_builder().create()
    listener = event.listener_builder().create()
    print("seq,status,x,y,theta,cost,hypotheses,map_version", flush=True)
    seen = 0
    last = None
    while args.count == 0 or seen < args.count:
        now = time.monotonic()
        if args.idle and last is not None and now - last > args.idle:
            break
        if now > deadline:
            sys.exit(f"timed out after {seen} poses")
        # wake on the pipeline's notification; look anyway now and then (a missed wake-up)
        listener.timed_wait(iox2.Duration.from_millis(100))
        while args.count == 0 or seen < args.count:
            sample = subscriber.receive()
            if sample is None:
                break
            m = sample.payload().contents
            best = m.hypotheses[0] if m.count > 0 and m.status != 2 else None
            pose = (best.pose.x, best.pose.y, best.pose.theta, best.cost) if best else (float("nan"),) * 4
            status = STATUS.get(m.status, "unknown")
            print(f"{m.header.seq},{status},{pose[0]:.4f},{pose[1]:.4f},{pose[2]:.5f},{pose[3]:.4f},{m.count},{m.map_version}", flush=True)
            seen += 1
            last = time.monotonic()


if __name__ == "__main__":
    main()
