#!/usr/bin/python3
"""A control loop with lgvi.Stepper: hover a body in uniform gravity.

The body falls in g = (0, 0, -9.81); a thruster fixed in the inertial frame
pushes with force u(t) = m g_up + PD control on the height, recomputed every
step. The thrust is a potential written in Python (V = -u . x, force u, no
torque) that reads the current command from a dict; after changing it,
stepper.refresh() makes the next step start from the new force.

    /usr/bin/python3 examples/control_loop.py [--duration T]
"""

import argparse

import numpy as np

import lgvi

G = np.array([0.0, 0.0, -9.81])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=10.0, help="simulated time (default 10)")
    parser.add_argument("--target", type=float, default=1.0, help="height to hover at (default 1)")
    args = parser.parse_args(argv)

    body = lgvi.Body(mass=2.0, inertia=np.diag([0.1, 0.2, 0.25]))
    scenario = lgvi.Scenario(body=body, step=0.01, duration=args.duration,
                             position=(0.0, 0.0, 0.0), quaternion=(1.0, 0.0, 0.0, 0.0),
                             momentum=(0.0, 0.0, 0.0), omega=(0.0, 0.0, 1.0))
    command = {"u": np.zeros(3)}  # the thrust, changed by the controller between steps

    def gravity_and_thrust(x, q):
        """V = -m g . x - u . x: force m g + u, no torque. q (scalar-first (w, x, y, z)) unused."""
        force = body.mass * G + command["u"]
        return -float(force @ x), force, np.zeros(3)

    stepper = lgvi.Stepper(scenario, potential=lgvi.PythonPotential(gravity_and_thrust))
    kp, kd = 20.0, 8.0
    print("|  t | height | vertical velocity | thrust |")
    print("|---:|---:|---:|---:|")
    while stepper.k < scenario.steps:
        z, vz = stepper.position[2], stepper.velocity[2]
        command["u"] = np.array([0.0, 0.0, body.mass * (9.81 + kp * (args.target - z) - kd * vz)])
        stepper.refresh()  # forces at the current state with the new command
        stepper.step()
        if stepper.k % max(1, scenario.steps // 10) == 0:
            print(f"| {stepper.t:.2f} | {stepper.position[2]:.6f} | {stepper.velocity[2]:.3e} | "
                  f"{command['u'][2]:.4f} |")
    print(f"\nfinal height {stepper.position[2]:.6f} (target {args.target}); the body spins freely: "
          f"omega = {np.round(stepper.omega, 12)}")


if __name__ == "__main__":
    main()
