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

    /usr/bin/python3 scripts/compare_manchester_peck_gyrostat.py MP_REPO --case motor [--steps 0.1,0.05,0.025]
        [--T 60] [--rhohist ends|middles|starts|all]

--case motor: the same gyrostat with its rotors spun up and down by internal (motor) torques, held:
u = (+0.002, -0.001, +0.0015) N m on the x, y, z rotors for 0 <= t < 20 s, -u for 20 <= t < 40 s, none after,
so that the rotor momentum in body axes, rho(t) = rho0 + the integral of u, goes to rho0 + 20 u = (0.03, 0,
0.04) and back to rho0 at t = 40 (the switches lie on the grid of every step size here); t in [0, 60].
lgvi's side (examples/gyrostat.cpp --motor) takes them as wheel torques (HeldTorque tables through
set_wheel_torques): each step gives each wheel half the exact impulse of its held command before the
implicit solve and half after, so the solve sees h_w = rho(t_k + h/2) and the step ends at rho(t_{k+1}).
GyrostatQVI.m takes no motor torque, only a rotor momentum history rhohist (its tauhist is an external
torque, zero here). Its step k (1-based, t(k) -> t(k+1)) reads the one column rhohist(:, k+1) both in its
discrete equation P(f)(I phi + (h/2) rho) = (h/2) p_k and in whist(:, k+1) = I^-1 (p_{k+1} - rho) at t(k+1);
column 1 only forms p_1 = I w0 + rhohist(:, 1). No history is right for both, and the script runs three
(rotor_history): "ends", column k = rho(t(k)), as their header documents rhohist (the step's equation sees
rho at its end: first order); "middles", column k+1 = rho(t(k) + h/2) (the equation is lgvi's: the two agree
to the solvers' rounding, but their omega at t(k+1) is formed with rho h/2 early, off by I^-1 u h/2 while a
torque acts); "starts", column k+1 = rho(t(k)), GyrostatDemo.m's layout (rho at the step's start: first
order). Prints, per layout and step size: the largest angle between the attitudes, the largest differences
of omega and of Pi = J_s omega + h_w, each method's largest angle to a continuous reference (RK4 in numpy at
dt = the smallest h / 8, rho exact), each one's drift of pi(q) Pi (GyrostatQVI.m's with the p its step
carries, I omega + the rhohist column its omega was formed with, and with I omega + rho(t_k), the momentum
its omega implies at t_k), the times per step; then the ratios of the differences per step of the list.
"""

import argparse
import pathlib
import shutil
import subprocess
import sys
import tempfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]



# Their run: rhohist is the script's (constant in the free case, rotor_history's in the motor case), read
# from RHO (one column of rhohist a row). L is pi(q_k) p_k with their own total momentum p_k = I whist(:, k) + rhohist(:, k) (GyrostatQVI.m
# forms whist(:, k) as I^-1 (p_k - rhohist(:, k))): the momentum their step carries.
OCTAVE_DRIVER = r"""
addpath('{repo}');
I = diag([1 2 3]);
w0 = [pi/10 pi/6 pi/8]';
q0 = [0 0 0 1]';
dt = {h};
T = {T};
n = round(T/dt);
rhohist = dlmread('{rho}')';
tauhist = zeros(3, n + 1);
tic;
[t, qhist, whist] = GyrostatQVI(I, q0, w0, rhohist, tauhist, dt, [0 T]);
elapsed = toc;
L = zeros(3, length(t));
for k = 1:length(t)
  L(:, k) = qrot(qhist(:, k), I*whist(:, k) + rhohist(:, k));
end
out = [t' qhist(4, :)' qhist(1:3, :)' whist' L'];
dlmwrite('{csv}', out, 'precision', 17);
printf('%.9g\n', elapsed / (length(t) - 1));
"""


def run_lgvi(binary, h, T, csv, motor=False):
    args = [str(binary)] + (["--motor"] if motor else []) + [repr(h), repr(T), str(csv)]
    proc = subprocess.run(args, capture_output=True, text=True, check=True)
    seconds_per_step = float(proc.stderr.split("(")[1].split(" ns/step")[0]) * 1e-9
    return np.loadtxt(csv, delimiter=",", skiprows=1), seconds_per_step


def run_octave(octave, repo, h, T, work, rho=None):
    """Their trajectory (t, q scalar first, omega, L) and seconds per step, given `rho` (rhohist, 3 x columns;
    None: the free case's constant rotor momentum, n + 2 columns as GyrostatDemo.m)."""
    csv = work / f"mp-{h}.csv"
    driver = work / "driver.m"
    if rho is None:
        rho = np.repeat(ROTOR[:, None], round(T / h) + 2, axis=1)
    rho_csv = work / f"rho-{h}.csv"
    np.savetxt(rho_csv, rho.T, delimiter=",", fmt="%.17g")
    driver.write_text(OCTAVE_DRIVER.format(repo=repo, h=repr(h), T=repr(T), csv=csv, rho=rho_csv))
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


# The motor case (examples/gyrostat.cpp --motor holds the same commands): torque u on the x, y, z rotors for
# 0 <= t < 20, -u for 20 <= t < 40, none after; the switches fall on the grid of every step size used here.
MOTOR_TORQUE = np.array([0.002, -0.001, 0.0015])
MOTOR_SWITCHES = (20.0, 40.0)
LAYOUTS = ("ends", "middles", "starts")


def rotor_momentum(t):
    """rho(t) = rho0 + the integral of u over [0, t], a row for each time in t (exact: u is held)."""
    t = np.asarray(t, dtype=float)[:, None]
    a, b = MOTOR_SWITCHES
    return ROTOR + MOTOR_TORQUE * (np.minimum(t, a) - np.clip(t - a, 0.0, b - a))


def rotor_history(layout, h, n):
    """GyrostatQVI.m's rhohist (3 x columns) for n steps of h, t(k) = (k - 1) h in their 1-based indexing.
    Their step k (t(k) -> t(k + 1)) reads column k + 1 for both the rotor momentum of its discrete equation
    and the one that turns p_{k+1} into whist(:, k + 1); column 1 only forms p_1 = I w0 + rhohist(:, 1).
      ends:    column k = rho(t(k)), 3 x (n + 1), as their header says ("rotor momentum", 3 x length(t)):
               the step's equation sees rho at the step's end.
      middles: column 1 = rho0, column k + 1 = rho(t(k) + h/2): the step's equation is lgvi's (rho at the
               step's middle); whist(:, k + 1) is then formed with rho h/2 before t(k + 1).
      starts:  column 1 = rho0, column k + 1 = rho(t(k)), 3 x (n + 2), GyrostatDemo.m's layout (it sums the
               torque samples by the trapezoidal rule, which for a held torque smears a switch over a step;
               here the exact integral): the step's equation sees rho at the step's start."""
    k = np.arange(n + 1)
    if layout == "ends":
        return rotor_momentum(k * h).T
    if layout == "middles":
        return np.vstack([ROTOR, rotor_momentum((k[:-1] + 0.5) * h)]).T
    return np.vstack([ROTOR, rotor_momentum(k * h)]).T


def continuous_reference(T, dt):
    """The continuous gyrostat, q' = q (0, omega) / 2, Pi' = Pi x omega, omega = J_s^-1 (Pi - rho(t)), by
    classical RK4 with step dt (rho exact at every stage; its kinks at the switches on dt's grid, so the
    order is 4): q (scalar first) and Pi at t = k dt, k = 0 .. round(T / dt)."""
    js_inverse = np.linalg.inv(JS)
    omega0 = np.array([np.pi / 10, np.pi / 6, np.pi / 8])

    def rate(t, q, p):
        omega = js_inverse @ (p - rotor_momentum([t])[0])
        dq = 0.5 * qmul(q[None, :], np.concatenate([[0.0], omega])[None, :])[0]
        return dq, np.cross(p, omega)

    n = int(round(T / dt))
    q, p = np.array([1.0, 0.0, 0.0, 0.0]), JS @ omega0 + ROTOR
    qs, ps = [q], [p]
    for k in range(n):
        t = k * dt
        a = rate(t, q, p)
        b = rate(t + dt / 2, q + dt / 2 * a[0], p + dt / 2 * a[1])
        c = rate(t + dt / 2, q + dt / 2 * b[0], p + dt / 2 * b[1])
        d = rate(t + dt, q + dt * c[0], p + dt * c[1])
        q = q + dt / 6 * (a[0] + 2 * b[0] + 2 * c[0] + d[0])
        p = p + dt / 6 * (a[1] + 2 * b[1] + 2 * c[1] + d[1])
        q = q / np.linalg.norm(q)
        qs.append(q)
        ps.append(p)
    return np.array(qs), np.array(ps)


def angles(qa, qb):
    """The angle of the rotation between attitudes, rows of scalar-first quaternions: 2 asin |Im(qa^* qb)|
    (arccos of the dot product loses half the digits near 1)."""
    relative = qmul(qa * np.array([1.0, -1.0, -1.0, -1.0]), qb)
    return 2.0 * np.arcsin(np.minimum(1.0, np.linalg.norm(relative[:, 1:], axis=1)))


def momentum_drift(inertial):
    """max_k |L_k - L_0| / |L_0| over rows of inertial angular momenta."""
    return np.linalg.norm(inertial - inertial[0], axis=1).max() / np.linalg.norm(inertial[0])


def rotate(q, v):
    """Rows of v rotated by the rows of scalar-first unit quaternions q (body to inertial): q (0, v) q^*."""
    qv = qmul(q, np.hstack([np.zeros((len(v), 1)), v]))
    return qmul(qv, q * np.array([1.0, -1.0, -1.0, -1.0]))[:, 1:]


def motor_case(args, repo, binary, work):
    """The motor case's table: per layout of their rhohist and step size, the two trajectories against
    each other and against the RK4 reference, each one's momentum drift and time per step; then the ratios
    of those differences per halving of h."""
    steps = [float(x) for x in args.steps.split(",")]
    layouts = LAYOUTS if args.rhohist == "all" else (args.rhohist,)
    dt = min(steps) / 8
    ref_q = continuous_reference(args.T, dt)[0]
    print(f"Manchester & Peck's gyrostat (GyrostatDemo.m) with motor torques u = {tuple(MOTOR_TORQUE)} N m on its "
          f"rotors for 0 <= t < {MOTOR_SWITCHES[0]:g}, -u to t = {MOTOR_SWITCHES[1]:g}, none after; "
          f"t in [0, {args.T:g}], reference RK4 at dt = {dt:g}:\n")
    print("| h | rhohist(:, k+1) holds rho at | max angle between q (rad) | max abs(omega difference) (rad/s) "
          "| max abs(Pi difference) (N m s) | lgvi max angle to RK4 | GyrostatQVI.m max angle to RK4 "
          "| lgvi max abs(L - L0)/abs(L0) | GyrostatQVI.m max abs(L - L0)/abs(L0), its p "
          "| the same, I omega + rho(t) | lgvi s/step | Octave s/step |")
    print("|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    ours_by_h, measured = {}, {}
    for layout in layouts:
        for h in steps:
            n = int(round(args.T / h))
            stride = int(round(h / dt))
            assert abs(stride * dt - h) < 1e-12 * h, (h, dt)
            if h not in ours_by_h:
                ours_by_h[h] = run_lgvi(binary, h, args.T, work / f"lgvi-{h}.csv", motor=True)
            (ours, t_ours) = ours_by_h[h]
            # lgvi's wheels carry the momentum the script gives their code (the two schedules agree).
            assert np.abs(ours[:, 11:14] - rotor_momentum(ours[:, 0])).max() < 1e-13
            rho = rotor_history(layout, h, n)
            theirs, t_theirs = run_octave(args.octave, repo, h, args.T, work, rho=rho)
            assert ours.shape[0] == theirs.shape[0] == n + 1, (ours.shape, theirs.shape, n)
            # Pi = J_s omega + h_w: lgvi's from its own h_w; theirs is the p their step carries (the rhohist
            # column their omega was formed with), and with rho(t_k) the momentum their omega implies at t_k.
            pi_ours = ours[:, 5:8] @ JS.T + ours[:, 11:14]
            pi_theirs = theirs[:, 5:8] @ JS.T + rho[:, : n + 1].T
            implied = rotate(theirs[:, 1:5], theirs[:, 5:8] @ JS.T + rotor_momentum(theirs[:, 0]))
            m = {
                "angle": angles(ours[:, 1:5], theirs[:, 1:5]).max(),
                "omega": np.abs(ours[:, 5:8] - theirs[:, 5:8]).max(),
                "Pi": np.abs(pi_ours - pi_theirs).max(),
                "lgvi-ref": angles(ours[:, 1:5], ref_q[::stride]).max(),
                "mp-ref": angles(theirs[:, 1:5], ref_q[::stride]).max(),
            }
            measured[layout, h] = m
            print(f"| {h:g} | {layout} | {m['angle']:.2e} | {m['omega']:.2e} | {m['Pi']:.2e} | {m['lgvi-ref']:.2e} "
                  f"| {m['mp-ref']:.2e} | {momentum_drift(ours[:, 8:11]):.2e} | {momentum_drift(theirs[:, 8:11]):.2e} "
                  f"| {momentum_drift(implied):.2e} | {t_ours:.2e} | {t_theirs:.2e} |")
    if len(steps) < 2:
        return
    print("\nRatios per step of the list (the column's value at h before / at h after; per halving 4 for second "
          "order, 2 for first; differences at round-off have no order):\n")
    print("| rhohist holds rho at | h | angle between q | omega difference | Pi difference | lgvi to RK4 "
          "| GyrostatQVI.m to RK4 |")
    print("|---|---|---:|---:|---:|---:|---:|")
    keys = ("angle", "omega", "Pi", "lgvi-ref", "mp-ref")
    for layout in layouts:
        for a, b in zip(steps, steps[1:]):
            ratios = " | ".join(f"{measured[layout, a][key] / measured[layout, b][key]:.2f}" for key in keys)
            print(f"| {layout} | {a:g} -> {b:g} | {ratios} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("repo", help="a checkout of zacmanchester/quaternion-variational-integrators")
    ap.add_argument("--case", choices=("free", "motor"), default="free",
                    help="free: constant rotor momentum (their demo's); motor: rotors driven by held torques")
    ap.add_argument("--steps", help="step sizes, comma-separated (free: 0.1,0.05; motor: 0.1,0.05,0.025)")
    ap.add_argument("--T", type=float, help="duration (free: their demo's 300 s; motor: 60 s)")
    ap.add_argument("--rhohist", choices=LAYOUTS + ("all",), default="all",
                    help="motor: which rho their rhohist holds for each step (rotor_history); all: each in turn")
    ap.add_argument("--octave", default=shutil.which("octave-cli") or "octave-cli")
    args = ap.parse_args()
    motor = args.case == "motor"
    args.steps = args.steps or ("0.1,0.05,0.025" if motor else "0.1,0.05")
    args.T = args.T if args.T is not None else (60.0 if motor else 300.0)
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
        if motor:
            motor_case(args, repo, binary, work)
            return
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
