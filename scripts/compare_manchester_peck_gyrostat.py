#!/usr/bin/python3
"""lgvi's gyrostat step against Manchester & Peck's gyrostat QVI (GyrostatQVI.m, run with Octave), on their
demo's free gyrostat (GyrostatDemo.m: I = diag(1, 2, 3) without the rotors' axial inertia, rotor momentum
(-0.01, 0.02, 0.01) in body axes held constant, Omega0 = (pi/10, pi/6, pi/8), q0 = identity, no torque).

    /usr/bin/python3 scripts/compare_manchester_peck_gyrostat.py MP_REPO [--steps 0.1,0.05] [--T 300]

MP_REPO: a checkout of zacmanchester/quaternion-variational-integrators (their code is run where it is,
never copied). lgvi's side is examples/gyrostat.cpp (three axis wheels of moment 0.01, so that lgvi's J with
the wheels locked is diag(1, 2, 3) + 0.01 I), compiled here with g++ against include/. Both solve the same
discrete equation, P(J_s f_v + (h/2) h_w) = (h/2) Pi_k with P(u) = f_s u + f_v x u (wheels.hpp), and rotate
Pi by the same f: with constant rotor momentum the two differ only by how far each solves it (lgvi to
4 eps; GyrostatQVI.m takes 3 Newton iterations per step). Prints, per step size, the largest differences in
q and omega over the run, the largest residual of that equation at each method's own steps (f_k = q_k^*
q_{k+1} and Pi_k = J_s omega_k + h_w from its trajectory, relative to |h Pi_k / 2|), each method's drift of
the inertial angular momentum pi(q) Pi, and the time per step of each (Octave interprets GyrostatQVI.m: the ratio says what the compiled step costs, not a
like-for-like comparison of implementations). Needs octave-cli (Debian: apt-get install octave).
"""

import argparse
import pathlib
import shutil
import subprocess
import sys
import tempfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]

OCTAVE_DRIVER = r"""
addpath('{repo}');
I = diag([1 2 3]);
w0 = [pi/10 pi/6 pi/8]';
q0 = [0 0 0 1]';
r0 = [-.01 .02 .01]';
dt = {h};
T = {T};
n = round(T/dt);
rhohist = repmat(r0, 1, n + 2);
tauhist = zeros(3, n + 1);
tic;
[t, qhist, whist] = GyrostatQVI(I, q0, w0, rhohist, tauhist, dt, [0 T]);
elapsed = toc;
L = zeros(3, length(t));
for k = 1:length(t)
  L(:, k) = qrot(qhist(:, k), I*whist(:, k) + r0);
end
out = [t' qhist(4, :)' qhist(1:3, :)' whist' L'];
dlmwrite('{csv}', out, 'precision', 17);
printf('%.9g\n', elapsed / (length(t) - 1));
"""


def run_lgvi(binary, h, T, csv):
    proc = subprocess.run([str(binary), repr(h), repr(T), str(csv)], capture_output=True, text=True, check=True)
    seconds_per_step = float(proc.stderr.split("(")[1].split(" ns/step")[0]) * 1e-9
    return np.loadtxt(csv, delimiter=",", skiprows=1), seconds_per_step


def run_octave(octave, repo, h, T, work):
    csv = work / f"mp-{h}.csv"
    driver = work / "driver.m"
    driver.write_text(OCTAVE_DRIVER.format(repo=repo, h=repr(h), T=repr(T), csv=csv))
    proc = subprocess.run([octave, "--no-gui", "--quiet", "--no-window-system", str(driver)], capture_output=True,
                          text=True, cwd=work)
    if proc.returncode != 0:
        sys.exit(f"octave failed: {proc.stderr or proc.stdout}")
    return np.loadtxt(csv, delimiter=","), float(proc.stdout.strip().splitlines()[-1])


JS = np.diag([1.0, 2.0, 3.0])
ROTOR = np.array([-0.01, 0.02, 0.01])


def qmul(a, b):
    """Hamilton products of rows of scalar-first quaternions."""
    s = a[:, :1] * b[:, :1] - np.sum(a[:, 1:] * b[:, 1:], axis=1, keepdims=True)
    v = a[:, :1] * b[:, 1:] + b[:, :1] * a[:, 1:] + np.cross(a[:, 1:], b[:, 1:])
    return np.hstack([s, v])


def residual(rows, h):
    """max_k |P(J_s f_v + (h/2) h_w) - (h/2) Pi_k| / |(h/2) Pi_k| over a trajectory's steps."""
    q, omega = rows[:, 1:5], rows[:, 5:8]
    f = qmul(q[:-1] * np.array([1.0, -1.0, -1.0, -1.0]), q[1:])
    fs, fv = f[:, :1], f[:, 1:]
    u = fv @ JS.T + 0.5 * h * ROTOR
    b = 0.5 * h * (omega[:-1] @ JS.T + ROTOR)
    r = fs * u + np.cross(fv, u) - b
    return (np.linalg.norm(r, axis=1) / np.linalg.norm(b, axis=1)).max()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("repo", help="a checkout of zacmanchester/quaternion-variational-integrators")
    ap.add_argument("--steps", default="0.1,0.05", help="step sizes, comma-separated")
    ap.add_argument("--T", type=float, default=300.0, help="duration (their demo's: 300 s)")
    ap.add_argument("--octave", default=shutil.which("octave-cli") or "octave-cli")
    args = ap.parse_args()
    repo = pathlib.Path(args.repo).resolve()
    if not (repo / "GyrostatQVI.m").is_file():
        sys.exit(f"{repo}: no GyrostatQVI.m here (a checkout of zacmanchester/quaternion-variational-integrators?)")
    if shutil.which(args.octave) is None:
        sys.exit("octave-cli not found (Debian: apt-get install octave)")
    with tempfile.TemporaryDirectory() as tmp:
        work = pathlib.Path(tmp)
        binary = work / "gyrostat"
        subprocess.run(["g++", "-O2", "-std=c++20", "-fopenmp", "-I", str(ROOT / "include"), "-I", "/usr/include/eigen3",
                        str(ROOT / "examples" / "gyrostat.cpp"), "-o", str(binary)], check=True)
        print(f"Manchester & Peck's free gyrostat (GyrostatDemo.m), t in [0, {args.T:g}]:\n")
        print("| h | max angle between q (rad) | max abs(omega difference) (rad/s) | lgvi residual | GyrostatQVI.m "
              "residual | lgvi max abs(L - L0)/abs(L0) | GyrostatQVI.m max abs(L - L0)/abs(L0) | lgvi s/step "
              "| Octave s/step |")
        print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        for h in (float(x) for x in args.steps.split(",")):
            ours, t_ours = run_lgvi(binary, h, args.T, work / f"lgvi-{h}.csv")
            theirs, t_theirs = run_octave(args.octave, repo, h, args.T, work)
            assert ours.shape == theirs.shape, (ours.shape, theirs.shape)
            # The angle of the rotation between the two attitudes, 2 asin |Im(q_ours^* q_theirs)| (arccos of the
            # dot product loses half the digits near 1).
            relative = qmul(ours[:, 1:5] * np.array([1.0, -1.0, -1.0, -1.0]), theirs[:, 1:5])
            angle = 2.0 * np.arcsin(np.minimum(1.0, np.linalg.norm(relative[:, 1:], axis=1)))
            domega = np.abs(ours[:, 5:8] - theirs[:, 5:8]).max()
            drift = [np.linalg.norm(r[:, 8:11] - r[0, 8:11], axis=1).max() / np.linalg.norm(r[0, 8:11])
                     for r in (ours, theirs)]
            print(f"| {h:g} | {angle.max():.2e} | {domega:.2e} | {residual(ours, h):.1e} | {residual(theirs, h):.1e} "
                  f"| {drift[0]:.2e} | {drift[1]:.2e} | {t_ours:.2e} | {t_theirs:.2e} |")


if __name__ == "__main__":
    main()
