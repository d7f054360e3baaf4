"""A robot among pedestrians, replanning every 0.1 s through the riskplan service.

Run `riskplan serve` first, then `python clients/python/examples/receding.py`. The robot
crosses a corridor while three pedestrians walk towards it; every step sends their
predictions (one acknowledged `apply`) and a receding-horizon plan request from the robot's
state, then moves the robot 0.1 s along the answer (docs/design.md §6.9).
"""
import math
import sys

import riskplan

ENDPOINT = sys.argv[1] if len(sys.argv) > 1 else "tcp/127.0.0.1:7447"
SCENE = "example-corridor"
GOAL = [6.0, 0.0]


def prediction(x, v, t):
    return {"position": x, "velocity": v, "time": t,
            "radius": {"dist": "uniform", "low": 0.2, "high": 0.3},
            "position_std": 0.02, "velocity_std": 0.05}


def main():
    walkers = {"p1": ([3.0, 0.3], [-0.8, 0.0]), "p2": ([5.0, -1.0], [-1.0, 0.1]), "p3": ([0.0, 1.5], [0.6, -0.2])}
    scene = {"format": "riskplan-scene/1", "name": SCENE, "dim": 2,
             "workspace": {"lower": [-8, -3], "upper": [8, 3]}, "horizon": [0, 60], "risk": 0.01,
             "robot_radius": 0.25, "planner": {"max_speed": 1.5, "max_accel": 3.0},
             "obstacles": [{"id": k, "pedestrian": prediction(x, v, 0.0)} for k, (x, v) in walkers.items()]}
    with riskplan.Client(ENDPOINT) as c:
        c.apply(SCENE, scene=scene)
        x, v, t = [-6.0, 0.0], [0.0, 0.0], 0.0
        plan = None
        while t < 30.0 and math.dist(x, GOAL) > 1e-6:
            c.update_pedestrians(SCENE, {k: prediction([p[0] + u[0] * t, p[1] + u[1] * t], u, t)
                                         for k, (p, u) in walkers.items()})
            try:
                plan = c.replan(SCENE, t, x, GOAL, horizon=3.0, velocity=v, robot_id="example-robot",
                                time_limit=0.05)
            except riskplan.NoPlanError as e:
                print(f"t = {t:.1f}: no plan ({e}); keeping the previous one")
            if plan is None:
                break
            t = round(t + 0.1, 10)
            x, v = [float(c) for c in plan.position(t)], [float(c) for c in plan.velocity(t)]
            if t % 1.0 < 0.05:
                print(f"t = {t:.1f}: robot at ({x[0]:.2f}, {x[1]:.2f}), {plan.progress}")
        print("reached the goal" if math.dist(x, GOAL) <= 1e-6 else f"stopped at {x} at t = {t:.1f}")


if __name__ == "__main__":
    main()
