#!/usr/bin/env python3
"""Times IR-SIM (PyPI `ir-sim`) or IR-SIM-X (PyPI `irsim-x`) stepping a differential robot with a
2-D lidar on a ROS map_server map, for `mentalsim bench sim` to print beside our simulator.

Both packages install the same `irsim` module, so each needs its own interpreter (virtual
environment); this script runs under whichever one it is started with and says which it found.

Usage: irsim_bench.py SPEC.json
The spec (written by services/bench/src/sim.rs) gives the map's YAML path, the beam count, the
laser, the robot radius, the static obstacles (object footprints: IR-SIM is 2-D), the episodes'
start and goal poses and the number of steps. One JSON object is printed on stdout.

The map is made binary exactly as our simulator sees it (ROS trinary: a pixel is free only when
its occupancy probability is below free_thresh) and handed to IR-SIM as a PNG obstacle map.
"""

import importlib.metadata
import json
import math
import os
import sys
import tempfile
import time

import numpy as np


def read_pgm(path):
    """Reads a binary (P5) or ASCII (P2) PGM into a uint8/uint16 array (row 0 = top)."""
    with open(path, "rb") as f:
        data = f.read()
    tokens = []
    pos = 0
    # Header: magic, width, height, maxval, separated by whitespace, with # comments.
    while len(tokens) < 4:
        while data[pos : pos + 1].isspace():
            pos += 1
        if data[pos : pos + 1] == b"#":
            while data[pos : pos + 1] not in (b"\n", b""):
                pos += 1
            continue
        start = pos
        while not data[pos : pos + 1].isspace():
            pos += 1
        tokens.append(data[start:pos])
    magic, w, h, maxval = tokens[0], int(tokens[1]), int(tokens[2]), int(tokens[3])
    pos += 1
    if magic == b"P5":
        dtype = np.uint8 if maxval < 256 else np.dtype(">u2")
        img = np.frombuffer(data, dtype=dtype, count=w * h, offset=pos).reshape(h, w)
    elif magic == b"P2":
        img = np.array(data[pos:].split()[: w * h], dtype=np.int64).reshape(h, w)
    else:
        raise ValueError(f"{path}: not a PGM (magic {magic!r})")
    return img.astype(np.float64) / maxval


def read_yaml(path):
    """The six map_server keys we need, read without a YAML library's type guessing."""
    import yaml  # ir-sim depends on PyYAML

    with open(path) as f:
        meta = yaml.safe_load(f)
    return meta


def free_mask(yaml_path):
    meta = read_yaml(yaml_path)
    image = os.path.join(os.path.dirname(yaml_path), meta["image"])
    if image.endswith(".pgm"):
        value = read_pgm(image)
    else:
        import matplotlib.image as mpimg

        value = mpimg.imread(image)
        if value.ndim == 3:
            value = value[..., :3].mean(axis=2)
    if int(meta.get("negate", 0)):
        value = 1.0 - value
    occ = 1.0 - value
    free = occ < float(meta["free_thresh"])
    return meta, free


def main():
    spec = json.load(open(sys.argv[1]))
    import irsim

    try:
        package, version = "irsim-x", importlib.metadata.version("irsim-x")
    except importlib.metadata.PackageNotFoundError:
        package, version = "ir-sim", importlib.metadata.version("ir-sim")

    t0 = time.perf_counter()
    meta, free = free_mask(spec["yaml"])
    h, w = free.shape
    res = float(meta["resolution"])
    ox, oy = float(meta["origin"][0]), float(meta["origin"][1])
    tmp = tempfile.mkdtemp(prefix="irsim_bench_")
    png = os.path.join(tmp, "map.png")
    import matplotlib.image as mpimg

    # White free, black blocked; IR-SIM reads occupancy as 100 * (1 - grey) and blocks > 50.
    mpimg.imsave(png, np.where(free, 1.0, 0.0), cmap="gray", vmin=0.0, vmax=1.0)

    laser = spec["laser"]
    first = spec["episodes"][0]
    obstacles = []
    for o in spec["obstacles"]:
        if o["shape"] == "circle":
            shape = {"name": "circle", "radius": o["radius"]}
        else:
            shape = {"name": "rectangle", "length": o["length"], "width": o["width"]}
        obstacles.append({"shape": shape, "state": [o["x"], o["y"], o.get("yaw", 0.0)]})
    world = {
        "world": {
            "height": h * res,
            "width": w * res,
            "step_time": spec["control_period"],
            "sample_time": spec["control_period"],
            "offset": [ox, oy],
            "collision_mode": "stop",
            "control_mode": "auto",
            "obstacle_map": png,
        },
        "robot": [
            {
                "kinematics": {"name": "diff"},
                "shape": {"name": "circle", "radius": spec["robot_radius"]},
                "state": [first[0], first[1], first[2]],
                "goal": [first[3], first[4], 0.0],
                "vel_min": [0.0, -0.5],
                "vel_max": [0.8, 0.5],
                "goal_threshold": spec["goal_tolerance"],
                "sensors": [
                    {
                        "type": "lidar2d",
                        "range_min": laser["range_min"],
                        "range_max": laser["range_max"],
                        "angle_range": laser["fov"],
                        "number": spec["beams"],
                        "offset": [laser["x"], laser["y"], 0.0],
                        "noise": True,
                        "std": spec["range_noise"],
                    }
                ],
            }
        ],
    }
    if obstacles:
        world["obstacle"] = obstacles
    config = os.path.join(tmp, "world.yaml")
    with open(config, "w") as f:
        json.dump(world, f)  # JSON is YAML
    env = irsim.make(config, display=False, disable_all_plot=True, log_level="ERROR")
    build_s = time.perf_counter() - t0

    robot = env.robot
    episodes = spec["episodes"]
    e = 0
    max_steps = int(spec["steps"])
    max_seconds = float(spec.get("max_seconds", float("inf")))
    resets = 0
    steps = 0
    # One untimed step first: IR-SIM builds some of its geometry lazily on the first step.
    t0 = time.perf_counter()
    env.step([0.0, 0.0])
    first_step_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    while steps < max_steps and time.perf_counter() - t0 < max_seconds:
        steps += 1
        # The same heuristic as the Rust side: turn towards the goal, slow down when turning.
        s = robot.state[:, 0]
        g = robot.goal[:, 0]
        bearing = math.atan2(g[1] - s[1], g[0] - s[0]) - s[2]
        bearing = math.atan2(math.sin(bearing), math.cos(bearing))
        wv = max(-0.5, min(0.5, 1.5 * bearing))
        v = 0.6 * max(0.0, math.cos(bearing))
        env.step([v, wv])
        if robot.collision or robot.arrive:
            e = (e + 1) % len(episodes)
            x, y, yaw, gx, gy = episodes[e]
            robot.set_state([x, y, yaw])
            robot.set_goal([gx, gy, 0.0])
            resets += 1
    elapsed = time.perf_counter() - t0
    print(
        json.dumps(
            {
                "package": package,
                "version": version,
                "python": sys.version.split()[0],
                "beams": spec["beams"],
                "steps": steps,
                "episodes_reset": resets,
                "build_s": build_s,
                "first_step_s": first_step_s,
                "elapsed_s": elapsed,
                "steps_per_s": steps / elapsed if elapsed > 0 else None,
                "obstacles": len(obstacles),
            }
        )
    )


if __name__ == "__main__":
    main()
