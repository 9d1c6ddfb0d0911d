#!/bin/sh
# ctest interrupt.inside_klu: SIGINT while cvode/klu is inside its first KLU
# factorisation of the 6N×6N Jacobian (a library call with no callback to
# stop it; 200×200 particles) ends bench_integrators within 5 s (the
# interrupt watchdog, bench/signals.h), exit 130, one line on stderr, the
# finished run kept in the journal; the same command then resumes from it.
#   verify/interrupt_in_library.sh BENCH_INTEGRATORS SCENE_10K WORKDIR
set -u
bench=$1 scene10k=$2 work=$3
rm -rf "$work" && mkdir -p "$work" || exit 1
sed 's/^nu = 100/nu = 200/; s/^nv = 100/nv = 200/; s/^name = .*/name = "sheet_40k"/' "$scene10k" > "$work/sheet_40k.toml"
run() {
  "$bench" --scene "$work/sheet_40k.toml" --integrators sbdf2,cvode/klu --h 0.01 --rtols 1e-3 --t-end 0.02 \
    --reference none --repeat 1 --quiet --out "$work/k.h5" > "$work/out.txt" 2> "$work/err.txt" &
  pid=$!
}
interrupt() {  # waits until sbdf2's run is journalled and cvode/klu has run 3 s, then SIGINT; sets code, took
  i=0
  while [ ! -f "$work/k.h5.journal/0.run" ] && [ $i -lt 600 ]; do sleep 0.1; i=$((i + 1)); done
  sleep 3
  kill -0 $pid 2> /dev/null || { echo "FAIL: it ended before the interrupt: $(cat "$work/err.txt")"; exit 1; }
  t0=$(date +%s%N)
  kill -INT $pid
  wait $pid; code=$?
  took=$(( ($(date +%s%N) - t0) / 1000000 ))
}
fail=0
run; interrupt
echo "interrupted: exit $code after $took ms: $(cat "$work/err.txt")"
[ $code -eq 130 ] || { echo "FAIL: exit $code, not 130"; fail=1; }
[ $took -le 5000 ] || { echo "FAIL: $took ms to stop (limit 5000)"; fail=1; }
[ "$(wc -l < "$work/err.txt")" -eq 1 ] || { echo "FAIL: not one line on stderr"; fail=1; }
[ -f "$work/k.h5.journal/0.run" ] || { echo "FAIL: the finished run is not in the journal"; fail=1; }
[ -e "$work/k.h5" ] || [ -e "$work/k.h5.tmp" ] && { echo "FAIL: a result file was left"; fail=1; }
# The same command resumes: the finished run comes from the journal.
run; interrupt
grep -q "^1 of 2 runs from $work/k.h5.journal" "$work/out.txt" || {
  echo "FAIL: the rerun did not resume: $(cat "$work/out.txt")"; fail=1; }
echo "resumed: $(head -1 "$work/out.txt")"
exit $fail
