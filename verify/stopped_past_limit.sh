#!/bin/sh
# ctest interrupt.stopped_past_limit: a run stopped (SIGSTOP) for 9 s across
# its --time-limit of 3 s is not taken for a run stuck inside a library
# call: the watchdog (bench/signals.h) does not count the stop, so the
# process is not restarted; once continued, the run stops at its next
# deadline check as time_limit, and its message says the process was
# stopped for that time.
#   verify/stopped_past_limit.sh BENCH_INTEGRATORS WORKDIR
set -u
bench=$1 work=$2
rm -rf "$work" && mkdir -p "$work" || exit 1
fail=0
"$bench" --integrators bdf2 --h 0.0001 --t-end 100 --reference none --repeat 1 --time-limit 3 \
  --out "$work/stopped.h5" > "$work/out.txt" 2> "$work/err.txt" &
pid=$!
sleep 1
kill -STOP $pid
sleep 9
kill -CONT $pid
wait $pid
code=$?
echo "exit $code; stderr: $(cat "$work/err.txt")"
[ $code -eq 0 ] || { echo "FAIL: exit $code, not 0"; fail=1; }
grep -q "restarts\|library call" "$work/err.txt" && { echo "FAIL: the stop was taken for a stuck library call"; fail=1; }
grep -q "^bdf2 .* time_limit$" "$work/out.txt" || { echo "FAIL: no time_limit row: $(cat "$work/out.txt")"; fail=1; }
grep -q "the process was stopped (SIGSTOP, a suspended job) for [0-9.]* s" "$work/out.txt" ||
  { echo "FAIL: the row's message does not name the stop: $(grep -i limit "$work/out.txt")"; fail=1; }
exit $fail
