#!/bin/bash
# The round-off figures the documentation (docs/) gives for lgvi (paper table, composition orders,
# radial free flight (also in lgvi-lagrangian), 10^7-step orbit, random attitudes, the Lennard-Jones cluster):
#   scripts/roundoff_figures.sh build/lgvi [build/tests/lgvi_tests]
# Prints the summary maxima (q: max abs(abs(q) - 1), L: max relative momentum error, E:
# max abs energy error) and, from the trajectory, the relative abs(L - L0) of the paper table.
set -e
B=$1; T=${2:-}; W=$(mktemp -d); S=$(cd "$(dirname "$0")/.." && pwd)/scenarios
py() { /usr/bin/python3 -c "$1"; }
summ() { py "import json; s=json.load(open('$1/summary.json')); print('$2', 'q %.2g'%s['max_abs_quat_norm_error'], 'L %.2g'%s['max_momentum_error'], 'E %.4g'%s['max_abs_energy_error'])"; }
traj() { py "
import numpy as np
A=np.genfromtxt('$1/trajectory.csv',delimiter=',',names=True)
L=np.c_[A['Lx'],A['Ly'],A['Lz']]; d=np.linalg.norm(L-L[0],axis=1)/np.linalg.norm(L[0])
print('$2 traj: q %.2g L %.2g E %.3g'%(abs(A['quat_norm_error']).max(), d.max(), abs(A['energy_error']).max()))"; }
$B run $S/paper-orbit.toml --out $W/po --no-figures -q; summ $W/po paper-orbit; traj $W/po paper-orbit
$B run $S/paper.toml --out $W/p --no-figures -q; summ $W/p paper; traj $W/p paper
for o in 4 6 8; do sed "s/^\[integrator\]/[integrator]\norder = $o/" $S/paper-orbit.toml > $W/c$o.toml; $B run $W/c$o.toml --out $W/c$o --no-figures -q; summ $W/c$o order$o; done
sed -e 's/^step = 0.01/step = 1e-4/' -e 's/^duration = 1000.0/duration = 200.0/' -e 's/^every = 10/every = 10000/' $S/paper.toml > $W/r.toml; $B run $W/r.toml --out $W/r --no-figures -q; summ $W/r radial-free-flight; traj $W/r radial-free-flight
sed 's/^method = .*/method = "lgvi-lagrangian"/' $W/r.toml > $W/rl.toml; $B run $W/rl.toml --out $W/rl --no-figures -q; summ $W/rl radial-free-flight-lagrangian; traj $W/rl radial-free-flight-lagrangian
sed -e 's/^duration = .*/duration = 100000.0/' -e 's/^every = .*/every = 100000/' $S/paper-orbit.toml > $W/b.toml; $B run $W/b.toml --out $W/b --no-figures -q; summ $W/b orbit-1e7
$B ensemble $S/ensembles/paper-orbit-attitudes.toml --out $W/ens --threads 2 -q --no-figures > /dev/null 2>&1; py "
import numpy as np
A=np.genfromtxt('$W/ens/members.csv',delimiter=',',names=True)
print('attitudes', ' '.join('%s %.2g %.2g'%(k[8:12], np.median(A[k]), A[k].max()) for k in ['max_abs_energy_error','max_abs_quat_norm_error','max_momentum_error']))"
if [ -n "$T" ]; then
  for seed in 1 2 5 7 8 20261121; do
    LGVI_TEST_SEED=$seed "$T" --gtest_filter='*LennardJonesCluster*' | grep 'Lennard-Jones cluster' | sed "s/^/seed $seed /"
  done
fi
rm -rf "$W"
