#!/usr/bin/env python3
"""OMPL's PRM on the same inflated grid as ours, for `mentalsim bench prm`.

Reads a PGM of the inflated free space (255 = the robot may stand in the cell, row 0 of the
image = top row of the map) and a jobs file, one job per line:
    n run seed k resolution_cells start_x start_y goal_x goal_y
(coordinates in grid units: cells, x right, y up, origin at the map's lower-left corner).
Writes one CSV line per job to stdout:
    n,run,build_ms,search_ms,success,milestones,path
where path is "x y;x y;..." in grid units (empty when no path was found).

Validity of a state is the same test as ours: the cell containing the point is free. The motion
validator checks points every `resolution_cells` cells along an edge (OMPL's discrete checker).
"""
import sys
import time

import numpy as np
from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou


def read_pgm(path):
    with open(path, "rb") as f:
        data = f.read()
    # Header: P5 <ws> width <ws> height <ws> maxval <single ws> pixels
    fields = []
    pos = 0
    while len(fields) < 4:
        while data[pos : pos + 1].isspace():
            pos += 1
        start = pos
        while not data[pos : pos + 1].isspace():
            pos += 1
        fields.append(data[start:pos])
    pos += 1
    if fields[0] != b"P5":
        raise ValueError(f"{path}: not a binary PGM")
    w, h = int(fields[1]), int(fields[2])
    img = np.frombuffer(data, dtype=np.uint8, count=w * h, offset=pos).reshape(h, w)
    # Flip so that row 0 is the bottom row (lowest y), as in the map frame.
    return np.ascontiguousarray(img[::-1, :] == 255)


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: ompl_prm.py GRID.pgm JOBS.txt")
    free = read_pgm(sys.argv[1])
    h, w = free.shape
    free_list = free.tolist()  # list lookups are cheaper than numpy scalar indexing per call

    ou.setLogLevel(ou.LOG_WARN)
    jobs = [line.split() for line in open(sys.argv[2]) if line.strip()]
    if jobs:
        # OMPL's RNG seed must be set before any sampler exists; one seed per process.
        ou.RNG.setSeed(int(jobs[0][2]) or 1)

    for job in jobs:
        n, run, seed, k = (int(v) for v in job[:4])
        res_cells = float(job[4])
        sx, sy, gx, gy = (float(v) for v in job[5:9])

        space = ob.RealVectorStateSpace(2)
        bounds = ob.RealVectorBounds(2)
        bounds.setLow(0, 0.0)
        bounds.setHigh(0, float(w))
        bounds.setLow(1, 0.0)
        bounds.setHigh(1, float(h))
        space.setBounds(bounds)
        si = ob.SpaceInformation(space)

        def valid(state):
            x, y = state[0], state[1]
            if x < 0.0 or y < 0.0:
                return False
            c, r = int(x), int(y)
            return c < w and r < h and free_list[r][c]

        si.setStateValidityChecker(valid)
        si.setStateValidityCheckingResolution(res_cells / space.getMaximumExtent())
        si.setup()

        start = space.allocState()
        start[0], start[1] = sx, sy
        goal = space.allocState()
        goal[0], goal[1] = gx, gy
        pdef = ob.ProblemDefinition(si)
        pdef.setStartAndGoalStates(start, goal)

        prm = og.PRM(si)
        prm.setMaxNearestNeighbors(k)
        prm.setProblemDefinition(pdef)
        prm.setup()

        t0 = time.perf_counter()
        prm.growRoadmapPtc(ob.PlannerTerminationCondition(lambda: prm.milestoneCount() >= n))
        t1 = time.perf_counter()
        status = prm.solve(ob.timedPlannerTerminationCondition(2.0))
        t2 = time.perf_counter()
        solved = pdef.hasExactSolution()
        path = ""
        if solved:
            sol = pdef.getSolutionPath()
            pts = [sol.getState(i) for i in range(sol.getStateCount())]
            path = ";".join(f"{p[0]:.6f} {p[1]:.6f}" for p in pts)
        print(
            f"{n},{run},{(t1 - t0) * 1e3:.4f},{(t2 - t1) * 1e3:.4f},{int(bool(solved))},"
            f"{prm.milestoneCount()},{path}",
            flush=True,
        )
        del status


if __name__ == "__main__":
    main()
