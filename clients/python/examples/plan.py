"""A robot asks Mentalsim for a plan, already driven in the mental simulation, and prints the path.

    MENTALSIM_URL=http://127.0.0.1:8080 MENTALSIM_TOKEN=<a robot's token> python examples/plan.py

It plans on the bundled sample building's ground floor (F0), from the living room to the hall.
The README shows this script; tests/test_20_plan.py runs it against the real binary.
"""

import math, os
from mentalsim_client import Client

with Client(os.environ.get("MENTALSIM_URL", "http://127.0.0.1:8080"), os.environ["MENTALSIM_TOKEN"]) as client:
    plan = client.plan("R-001", "F0", start=(0.5, -2.0, 1.57), goal=(-12.0, -1.0))
    print(f"validated by the {plan.controller} controller: {plan.distance_m:.1f} m in {plan.simulated_time_s:.0f} s simulated")
    for pose in plan.path.poses:  # a ROS nav_msgs/Path in the floor's map frame
        print(f"x={pose.x:.2f} y={pose.y:.2f} yaw={math.degrees(pose.yaw):.0f}°")
