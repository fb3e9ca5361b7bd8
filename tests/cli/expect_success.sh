#!/bin/sh
# A command-line success test.
#
#   expect_success.sh LGVI_BINARY OUTDIR EXPECTED_ROWS EXPECTED_LAST_T -- ARGS...
#
# Removes OUTDIR's trajectory.csv and summary.json (so that files of an
# earlier run cannot pass the test), runs LGVI_BINARY ARGS... (which should
# write into OUTDIR) and passes (exit 0) only if
#   - the exit status is 0 and standard error is empty,
#   - OUTDIR/trajectory.csv has the header line and EXPECTED_ROWS data rows of
#     21 columns, the last at t = EXPECTED_LAST_T (to 1e-12),
#   - OUTDIR/summary.json says "completed": true and "error": "",
#   - no temporary summary.json.tmp is left behind.
set -u

if [ $# -lt 5 ] || [ "$5" != "--" ]; then
  echo "usage: $0 LGVI_BINARY OUTDIR EXPECTED_ROWS EXPECTED_LAST_T -- ARGS..." >&2
  exit 2
fi
binary=$1
outdir=$2
expected_rows=$3
expected_last_t=$4
shift 5

csv="$outdir/trajectory.csv"
summary="$outdir/summary.json"
rm -f "$csv" "$summary" "$summary.tmp"

tmp=$(mktemp -d) || exit 1
trap 'rm -rf "$tmp"' EXIT

"$binary" "$@" >"$tmp/stdout" 2>"$tmp/stderr"
status=$?

echo "command: $binary $*"
echo "exit status: $status"
echo "--- stderr:"
cat "$tmp/stderr"
echo "--- stdout:"
cat "$tmp/stdout"
echo "---"

failed=0
fail() {
  echo "FAIL: $*"
  failed=1
}

[ "$status" = 0 ] || fail "exit status $status, expected 0"
[ -s "$tmp/stderr" ] && fail "stderr is not empty"

if [ ! -f "$csv" ]; then
  fail "$csv was not written"
else
  header=$(head -n 1 "$csv")
  case "$header" in
    t,x,y,z,qw,qx,qy,qz,px,py,pz,wx,wy,wz,*) ;;
    *) fail "$csv header is '$header'" ;;
  esac
  rows=$(($(wc -l <"$csv") - 1))
  [ "$rows" = "$expected_rows" ] || fail "$csv has $rows data rows, expected $expected_rows"
  bad_rows=$(awk -F, 'NR > 1 && NF != 21' "$csv" | wc -l | tr -d ' ')
  [ "$bad_rows" = 0 ] || fail "$csv has $bad_rows rows without 21 columns"
  last_t=$(tail -n 1 "$csv" | cut -d, -f1)
  awk -v a="$last_t" -v b="$expected_last_t" 'BEGIN { d = a - b; exit !(d < 1e-12 && d > -1e-12) }' ||
    fail "the last row is at t = $last_t, expected $expected_last_t"
fi

if [ ! -f "$summary" ]; then
  fail "$summary was not written"
else
  grep -Eq '"completed"[[:space:]]*:[[:space:]]*true' "$summary" || fail "$summary does not say \"completed\": true"
  grep -Eq '"error"[[:space:]]*:[[:space:]]*""' "$summary" || fail "$summary has a non-empty \"error\""
fi
[ -e "$summary.tmp" ] && fail "$summary.tmp was left behind"

[ "$failed" = 0 ] && echo "PASS"
exit "$failed"
