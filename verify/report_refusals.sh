#!/bin/sh
# ctest report_page.refusals: scripts/report REPORT on bad input exits 2 with
# one line naming the file or option, and writes nothing it does not own.
#   verify/report_refusals.sh REPORT GOOD.h5 WORKDIR
set -u
report=$1 good=$2 work=$3
rm -rf "$work" && mkdir -p "$work" || exit 1
fail=0
expect() {  # expect NAME NEEDLE -- command...: exit 2, one stderr line containing NEEDLE
  name=$1 needle=$2; shift 3
  "$@" > "$work/out" 2> "$work/err"; code=$?
  lines=$(wc -l < "$work/err")
  if [ "$code" -ne 2 ] || [ "$lines" -ne 1 ] || ! grep -qF -- "$needle" "$work/err"; then
    echo "FAIL $name: exit $code, $lines stderr lines: $(cat "$work/err")"; fail=1
  else
    echo "ok   $name: $(cat "$work/err")"
  fi
}
expect missing "No such file" -- "$report" "$work/none.h5"
printf 'not hdf5' > "$work/text.h5"
expect not_signed "no integrity block" -- "$report" "$work/text.h5"
cp "$good" "$work/cut.h5" && truncate -s -100 "$work/cut.h5"
expect cut_short "cut short" -- "$report" "$work/cut.h5"
# One byte inverted (not set: a byte that already held the value would not change).
byte=$(od -An -tu1 -j4096 -N1 "$good" | tr -d ' ')
cp "$good" "$work/flip.h5" && printf "\\$(printf '%03o' $((255 - byte)))" |
  dd of="$work/flip.h5" bs=1 seek=4096 conv=notrunc 2> /dev/null
expect damaged "CRC-32" -- "$report" "$work/flip.h5"
# A planted link at the page's path is neither followed nor replaced.
echo precious > "$work/victim.txt"
ln -s "$work/victim.txt" "$work/link.html"
expect planted_link "not a regular file" -- "$report" "$good" --out "$work/link.html"
# A file that is not a page of scripts/report is not replaced.
echo "my notes" > "$work/notes.html"
expect not_owned "not a clothbench report" -- "$report" "$good" --out "$work/notes.html"
# The result file itself is never the page.
cp "$good" "$work/self.h5"
expect self "the result file itself" -- "$report" "$work/self.h5" --out "$work/self.h5"
if [ "$(cat "$work/victim.txt")" != precious ] || [ "$(cat "$work/notes.html")" != "my notes" ] || \
   ! cmp -s "$good" "$work/self.h5"; then
  echo "FAIL: a refused run changed a file it does not own"; fail=1
fi
# Its own page it replaces, through PAGE.tmp, which it then removes.
"$report" "$good" --out "$work/own.html" > /dev/null && "$report" "$good" --out "$work/own.html" > /dev/null || {
  echo "FAIL: rewriting its own page"; fail=1; }
[ -e "$work/own.html.tmp" ] && { echo "FAIL: own.html.tmp left behind"; fail=1; }
exit $fail
