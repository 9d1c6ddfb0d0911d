#!/bin/sh
# ctest interrupt.time_limit_inside_klu: --time-limit 4 (and --start-predicted: KLU's analysis predicts the factorisation past it) while cvode/klu is
# inside its first KLU factorisation of the 6N×6N Jacobian (a library call
# with no callback, minutes long at 200×200 particles). The watchdog
# (bench/signals.h, WatchOverruns) ends the run 5 s past its limit:
# (4 s: with both cores busy, the setup and the Jacobian's assembly before
# the factorisation passed a limit of 2 s, and the run stopped there as
# time_limit without entering KLU, so without the overrun.)
#  - serial: the process restarts the same command, which resumes from the
#    journal and stores cvode/klu as time_limit (exit 0, one line on
#    stderr, the result file written, the journal gone);
#    a second command with the same --out, started during the restart, is
#    refused: the lock is held across it;
#  - one MPI rank (which cannot restart itself): exit 75 with one line, the
#    journal and the task's marker kept; the same command then finishes
#    with the same time_limit row.
#   verify/overrun_in_library.sh BENCH_INTEGRATORS SCENE_10K WORKDIR [MPIEXEC]
set -u
bench=$1 scene10k=$2 work=$3 mpiexec=${4:-}
rm -rf "$work" && mkdir -p "$work" || exit 1
sed 's/^nu = 100/nu = 200/; s/^nv = 100/nv = 200/; s/^name = .*/name = "sheet_40k"/' "$scene10k" > "$work/sheet_40k.toml"
fail=0
run() {  # run LAUNCHER OUT: sets code, took [ms]
  t0=$(date +%s%N)
  $1 "$bench" --scene "$work/sheet_40k.toml" --integrators sbdf2,cvode/klu --h 0.01 --rtols 1e-3 --t-end 0.02 \
    --reference none --repeat 1 --quiet --time-limit 4 --start-predicted --out "$2" > "$work/out.txt" 2> "$work/err.txt"
  code=$?
  took=$(( ($(date +%s%N) - t0) / 1000000 ))
}
check_row() {  # the printed table stores cvode/klu as time_limit, with the reason
  grep -q "^cvode/klu .* time_limit$" "$work/out.txt" || { echo "FAIL: no time_limit row: $(cat "$work/out.txt")"; fail=1; }
  grep -q "stayed inside one library call" "$work/out.txt" || { echo "FAIL: the row's reason is missing"; fail=1; }
  # sbdf2's row (journalled before cvode/klu starts) is there; its status
  # is not checked: on a loaded machine its 4·10⁴-particle setup may itself
  # pass the 4 s limit.
  grep -q "^sbdf2 " "$work/out.txt" || { echo "FAIL: sbdf2's row is missing"; fail=1; }
}

run "" "$work/serial.h5"
echo "serial: exit $code after $took ms: $(cat "$work/err.txt")"
[ $code -eq 0 ] || { echo "FAIL: exit $code, not 0"; fail=1; }
# 4 s of limit + 5 s of grace after sbdf2's run and the setup; the restart
# reads the journal and records the row at once. 60 s: a slow machine's margin,
# far below the factorisation's minutes.
[ $took -le 60000 ] || { echo "FAIL: $took ms (limit 60000)"; fail=1; }
[ "$(wc -l < "$work/err.txt")" -eq 1 ] || { echo "FAIL: not one line on stderr"; fail=1; }
grep -q "cvode/klu rtol 0.001 stayed inside one library call .* past --time-limit 4 s; the process restarts" \
  "$work/err.txt" || { echo "FAIL: the line does not say what overran"; fail=1; }
grep -q "^1 of 2 runs from $work/serial.h5.journal" "$work/out.txt" || { echo "FAIL: the restart did not resume"; fail=1; }
[ -f "$work/serial.h5" ] || { echo "FAIL: no result file"; fail=1; }
[ -e "$work/serial.h5.journal" ] && { echo "FAIL: the journal was left"; fail=1; }
check_row

# The output lock is kept across the restart: the same command, started as
# the restart line appears, is refused (exit 2), and the restarted command
# finishes with its file.
args="--scene $work/sheet_40k.toml --integrators sbdf2,cvode/klu --h 0.01 --rtols 1e-3 --t-end 0.02 --reference none
  --repeat 1 --quiet --time-limit 4 --start-predicted --out $work/locked.h5"
# shellcheck disable=SC2086
"$bench" $args > "$work/a_out.txt" 2> "$work/a_err.txt" &
first=$!
i=0
while ! grep -q "the process restarts" "$work/a_err.txt" 2> /dev/null && [ $i -lt 1200 ]; do sleep 0.05; i=$((i + 1)); done
# The first command is held (SIGSTOP; the restart keeps its pid) while the
# second one starts: otherwise, on a loaded machine, the restarted command
# could resume from its journal, write its file and release the lock
# before the second command's lock attempt, a legitimate order that the
# test would call a failure.
grep -q "the process restarts" "$work/a_err.txt" ||
  { echo "FAIL: the first command did not overrun inside KLU within 60 s: $(cat "$work/a_err.txt" "$work/a_out.txt")"; fail=1; }
kill -STOP $first 2> /dev/null
# shellcheck disable=SC2086
"$bench" $args > "$work/b_out.txt" 2> "$work/b_err.txt"
second=$?
kill -CONT $first 2> /dev/null
wait $first
first_code=$?
echo "during the restart: the second command exited $second: $(cat "$work/b_err.txt")"
[ $second -eq 2 ] && grep -q "is being written by process" "$work/b_err.txt" ||
  { echo "FAIL: a second command took the --out during the restart"; fail=1; }
[ $first_code -eq 0 ] && [ -f "$work/locked.h5" ] ||
  { echo "FAIL: the restarted command exited $first_code: $(cat "$work/a_err.txt")"; fail=1; }

if [ -n "$mpiexec" ]; then
  mpirun="env OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 $mpiexec -n 1"
  run "$mpirun" "$work/mpi.h5"
  echo "one rank: exit $code after $took ms: $(cat "$work/err.txt")"
  [ $code -eq 75 ] || { echo "FAIL: exit $code, not 75"; fail=1; }
  grep -q "past --time-limit 4 s; ended (exit 75)" "$work/err.txt" || { echo "FAIL: no exit-75 line"; fail=1; }
  [ -f "$work/mpi.h5.journal/0.run" ] && [ -f "$work/mpi.h5.journal/1.overrun" ] ||
    { echo "FAIL: the journal or the marker is missing: $(ls "$work/mpi.h5.journal")"; fail=1; }
  [ -e "$work/mpi.h5" ] && { echo "FAIL: a result file was written"; fail=1; }
  run "$mpirun" "$work/mpi.h5"
  echo "rerun: exit $code after $took ms"
  [ $code -eq 0 ] || { echo "FAIL: the rerun exited $code: $(cat "$work/err.txt")"; fail=1; }
  check_row
fi
exit $fail
