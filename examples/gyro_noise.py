#!/usr/bin/python3
"""Gyro noise, drawn once per control sample, in a PD attitude controller (an lgvi.PythonForcing).

A spacecraft (mass + inertia) detumbles under a PD law that reads a noisy gyro:
    M = -k_p e_v - k_d (Omega + n_k),  e = q_target^* q (e_s >= 0),
where n_k is the gyro's white noise of sample k = floor(t / period).

lgvi may evaluate a forcing more than once at the same time and state (the
end-of-step momenta are a fixed point when the forcing reads them), so the
forcing must be a function of (t, state): drawing fresh noise on every call
would give the step nothing to converge to, and lgvi stops with "the forcing
returned different values for the same time and state". The noise is
therefore drawn once per control sample from a generator seeded by (seed,
sample number), which every call at that sample reproduces.

    /usr/bin/python3 examples/gyro_noise.py [--duration T] [--noise SIGMA]
"""

import argparse

import numpy as np

import lgvi

J = np.diag([1.2, 1.5, 0.9])  # kg m^2


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=60.0, help="simulated time, s (default 60)")
    parser.add_argument("--noise", type=float, default=1e-3, help="gyro noise, rad/s per axis (default 1e-3)")
    parser.add_argument("--seed", type=int, default=7, help="the noise's seed (default 7)")
    args = parser.parse_args(argv)
    period, k_p, k_d = 0.1, 0.4, 1.2

    def gyro_noise(t):
        """The noise of the control sample containing t: one draw per sample number, the same
        on every call (numpy's generator seeded by the pair (seed, sample))."""
        sample = int(np.floor(t / period + 1e-9))  # the 1e-9: t = k h lands on n period exactly
        return np.random.default_rng([args.seed, sample]).normal(0.0, args.noise, 3)

    def controller(t, x, q, p, w):
        omega = 0.5 * np.linalg.solve(J, w)  # body angular velocity, w = 2 J Omega
        e_v = q[1:] if q[0] >= 0 else -q[1:]  # target: the identity attitude
        torque = -k_p * e_v - k_d * (omega + gyro_noise(t))
        return np.zeros(3), torque

    body = lgvi.Body(mass=50.0, inertia=J)
    q0 = np.array([0.9, 0.3, -0.2, 0.24])
    scenario = lgvi.Scenario(body=body, step=0.05, duration=args.duration,
                             position=(0.0, 0.0, 0.0), quaternion=q0 / np.linalg.norm(q0),
                             momentum=(0.0, 0.0, 0.0), omega=(0.05, -0.1, 0.08))
    result = lgvi.simulate(scenario, forcing=lgvi.PythonForcing(controller))
    print("|  t | attitude error (deg) | |Omega| (rad/s) | E - E0 - W |")
    print("|---:|---:|---:|---:|")
    rows = len(result.t)
    for i in np.unique(np.linspace(0, rows - 1, 7).astype(int)):
        q, w = result.q[i], result.w[i]
        angle = np.degrees(2 * np.arccos(min(1.0, abs(q[0]))))
        omega = np.linalg.norm(0.5 * np.linalg.solve(J, w))
        print(f"| {result.t[i]:.1f} | {angle:.4f} | {omega:.3e} | {result.columns['energy_error'][i]:.2e} |")
    print(f"\n|q| - 1 at most {np.max(np.abs(result.columns['quat_norm_error'])):.1e}; the controller holds "
          f"the attitude to the noise's level (k_d sigma / k_p ~ {np.degrees(k_d * args.noise / k_p):.2f} deg)")


if __name__ == "__main__":
    main()
