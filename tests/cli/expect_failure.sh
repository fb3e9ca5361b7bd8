#!/bin/sh
# A command-line failure test.
#
#   expect_failure.sh LGVI_BINARY EXPECTED_STATUS EXPECTED_REGEX OUTDIR -- ARGS...
#
# Runs LGVI_BINARY ARGS... and passes (exit 0) only if
#   - its exit status is EXPECTED_STATUS,
#   - its standard error matches EXPECTED_REGEX (grep -E),
#   - for bad input (status 2) its standard error is exactly one line,
#   - OUTDIR holds no summary.json claiming "completed": true (absent is fine).
# Otherwise prints what was wrong, with the captured output, and exits 1.
set -u

if [ $# -lt 5 ] || [ "$5" != "--" ]; then
  echo "usage: $0 LGVI_BINARY EXPECTED_STATUS EXPECTED_REGEX OUTDIR -- ARGS..." >&2
  exit 2
fi
binary=$1
expected_status=$2
expected_regex=$3
outdir=$4
shift 5

tmp=$(mktemp -d) || exit 1
trap 'rm -rf "$tmp"' EXIT

"$binary" "$@" >"$tmp/stdout" 2>"$tmp/stderr"
status=$?

echo "command: $binary $*"
echo "exit status: $status (expected $expected_status)"
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

[ "$status" = "$expected_status" ] || fail "exit status $status, expected $expected_status"

grep -Eq -- "$expected_regex" "$tmp/stderr" || fail "stderr does not match /$expected_regex/"

if [ "$expected_status" = 2 ]; then
  # Exactly one line: one newline, and nothing after it.
  newlines=$(wc -l <"$tmp/stderr" | tr -d ' ')
  records=$(awk 'END { print NR }' "$tmp/stderr")
  if [ "$newlines" != 1 ] || [ "$records" != 1 ]; then
    fail "stderr is not exactly one line ($records lines)"
  fi
fi

summary="$outdir/summary.json"
if [ -f "$summary" ] && grep -Eq '"completed"[[:space:]]*:[[:space:]]*true' "$summary"; then
  fail "$summary claims \"completed\": true"
fi

[ "$failed" = 0 ] && echo "PASS"
exit "$failed"
