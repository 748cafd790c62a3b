#!/usr/bin/env python3
"""Nav2's AMCL (PyPI `amcl`: Python bindings of nav2_amcl's particle filter, beam model and
differential motion model) as a line-protocol worker for `gema2 amcl`, which feeds it the
same scans and odometry that it feeds gema2's sequential localizer and judges both alike.

Protocol, one line each way (stdin -> stdout), whitespace-separated:
  map PATH.yaml                 -> map WIDTH HEIGHT FREE_CELLS
      a map_server map (`gema2 map export-ros` writes it): image, resolution, origin,
      negate, occupied_thresh, free_thresh.
  start [X Y THETA]             -> started PARTICLES
      a new filter, started globally: the particles are drawn from a Gaussian with the free
      cells' mean and covariance and a heading spread far wider than a turn (the bindings
      expose no uniform free-space start, Nav2's global_localization service). With a pose:
      started there instead (0.1 m and 0.05 rad), as a user's click in RViz starts it.
  scan OX OY OTH AMIN AINC RMIN RMAX N R0 .. RN-1
                                -> pose X Y THETA SECONDS
      the robot's odometry pose, the scan's angles (radians) and range limits (metres) and
      its ranges (nan for no reading). SECONDS is the filter's own time for this scan.
  anything wrong                -> error MESSAGE (and the worker goes on reading)

Run with the project's Python (`scripts/python-env`); `gema2 amcl` does.
"""

import argparse
import math
import sys
import time
from pathlib import Path

import amcl
import numpy as np


def parse_args():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--min-particles", type=int, default=500)
    p.add_argument("--max-particles", type=int, default=5000)
    p.add_argument("--max-beams", type=int, default=60)
    p.add_argument("--alphas", default="0.2,0.2,0.2,0.2,0.2", help="alpha1..alpha5 of the motion model")
    return p.parse_args()


def read_yaml(path):
    """The few map_server keys, from the flat YAML `gema2 map export-ros` and map_saver write."""
    meta = {}
    for line in Path(path).read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if ":" not in line:
            continue
        key, value = (s.strip() for s in line.split(":", 1))
        meta[key] = value
    for key in ("image", "resolution", "origin"):
        if key not in meta:
            raise ValueError(f"{path}: no {key}")
    origin = [float(v) for v in meta["origin"].strip("[]").split(",")]
    return {
        "image": Path(path).parent / meta["image"],
        "resolution": float(meta["resolution"]),
        "origin": origin,
        "negate": int(meta.get("negate", "0")),
        "occupied": float(meta.get("occupied_thresh", "0.65")),
        "free": float(meta.get("free_thresh", "0.196")),
    }


def read_pgm(path):
    """A binary (P5) PGM of 8-bit values, top row first."""
    data = Path(path).read_bytes()
    fields, pos = [], 0
    while len(fields) < 4:
        while data[pos : pos + 1].isspace():
            pos += 1
        if data[pos : pos + 1] == b"#":
            pos = data.index(b"\n", pos) + 1
            continue
        end = pos
        while not data[end : end + 1].isspace():
            end += 1
        fields.append(data[pos:end])
        pos = end
    magic, width, height, maxval = fields[0], int(fields[1]), int(fields[2]), int(fields[3])
    if magic != b"P5" or maxval > 255:
        raise ValueError(f"{path}: not an 8-bit binary PGM")
    pixels = np.frombuffer(data, dtype=np.uint8, count=width * height, offset=pos + 1)
    return pixels.reshape(height, width), maxval


class Worker:
    def __init__(self, args):
        self.args = args
        alphas = [float(v) for v in args.alphas.split(",")]
        if len(alphas) != 5:
            raise ValueError("--alphas takes five values")
        self.motion = amcl.MotionParameters(*alphas)
        # Nav2's defaults for the beam model
        self.laser = amcl.LaserParameters(0.5, 0.05, 0.05, 0.5, 0.2, 0.1, 0.05, args.max_beams)
        self.grid = None
        self.filter = None

    def load_map(self, yaml):
        meta = read_yaml(yaml)
        pixels, maxval = read_pgm(meta["image"])
        p = pixels.astype(np.float64) / maxval
        occ = p if meta["negate"] else 1.0 - p
        cells = np.full(pixels.shape, -1, dtype=np.int64)
        cells[occ > meta["occupied"]] = 100
        cells[occ < meta["free"]] = 0
        cells = cells[::-1]  # row 0 at the origin (bottom)
        height, width = cells.shape
        res, (ox, oy, _) = meta["resolution"], meta["origin"]
        self.grid = amcl.create_occupancy_grid_from_list(cells.tolist(), res, ox, oy)
        rows, cols = np.nonzero(cells == 0)
        if len(rows) < 2:
            raise ValueError(f"{yaml}: no free cell to start the particles in")
        xy = np.stack([ox + (cols + 0.5) * res, oy + (rows + 0.5) * res])
        self.prior_mean = xy.mean(axis=1)
        self.prior_cov = np.cov(xy)
        return f"map {width} {height} {len(rows)}"

    def start(self, pose):
        if self.grid is None:
            raise ValueError("start before map")
        a = self.args
        self.filter = amcl.AMCL(a.min_particles, a.max_particles, 0.0, 0.0, self.motion, self.laser, "differential")
        self.filter.set_map(self.grid)
        self.filter.set_laser_pose(amcl.Vector3D(0.0, 0.0, 0.0))
        cov = amcl.Matrix3D()
        if pose:
            x, y, theta = (float(v) for v in pose)
            mean = amcl.Vector3D(x, y, theta)
            cov.set(0, 0, 0.1**2)
            cov.set(1, 1, 0.1**2)
            cov.set(2, 2, 0.05**2)
        else:
            cov.set(0, 0, float(self.prior_cov[0, 0]))
            cov.set(0, 1, float(self.prior_cov[0, 1]))
            cov.set(1, 0, float(self.prior_cov[1, 0]))
            cov.set(1, 1, float(self.prior_cov[1, 1]))
            # a wrapped normal this wide is uniform in heading to within e^-19
            cov.set(2, 2, (2.0 * math.pi) ** 2)
            mean = amcl.Vector3D(float(self.prior_mean[0]), float(self.prior_mean[1]), 0.0)
        self.filter.set_initial_pose(mean, cov)
        return f"started {a.max_particles}"

    def scan(self, fields):
        if self.filter is None:
            raise ValueError("scan before start")
        ox, oy, oth, amin, ainc, rmin, rmax = (float(v) for v in fields[:7])
        n = int(fields[7])
        if len(fields) != 8 + n:
            raise ValueError(f"scan: {n} ranges announced, {len(fields) - 8} given")
        ranges = []
        for i, text in enumerate(fields[8:]):
            r = float(text)
            # as Nav2 does with a reading at or below the minimum: no return
            if not math.isfinite(r) or r <= rmin or r > rmax:
                r = rmax
            ranges.append([r, amin + i * ainc])
        t0 = time.perf_counter()
        scan = amcl.create_laser_scan_from_list(ranges, rmax)
        self.filter.update(scan, amcl.Vector3D(ox, oy, oth))
        pose = self.filter.get_pose_mean()
        seconds = time.perf_counter() - t0
        return f"pose {pose.x!r} {pose.y!r} {pose.theta!r} {seconds!r}"


def main():
    worker = Worker(parse_args())
    for line in sys.stdin:
        fields = line.split()
        if not fields:
            continue
        try:
            if fields[0] == "map" and len(fields) == 2:
                reply = worker.load_map(fields[1])
            elif fields[0] == "start" and len(fields) in (1, 4):
                reply = worker.start(fields[1:])
            elif fields[0] == "scan":
                reply = worker.scan(fields[1:])
            else:
                reply = f"error unknown request {fields[0]!r}"
        except Exception as e:  # noqa: BLE001 - every failure is a reply, never a dead worker
            reply = "error " + " ".join(str(e).split())
        print(reply, flush=True)


if __name__ == "__main__":
    main()
