#!/usr/bin/env bash
# scripts/check_citations must fail on planted dangling citations: a section
# docs/model.md does not have, a title it does not have, a member function
# that does not exist, and a citation of the spec the repository does not
# contain. Each must be named. (The citations are assembled from parts so
# that this file itself passes the check.)
#   citations_planted.sh SOURCE_DIR
set -uo pipefail
src=$1
planted=$(mktemp --suffix=.cc)
trap 'rm -f "$planted"' EXIT
doc="docs/model.md" cls="StepEngine" spec="SPEC"
printf '// See %s §42 and %s, "No such title".\n// Set up in %s::NoSuchMember (%s §5).\n' \
  "$doc" "$doc" "$cls" "$spec" > "$planted"
out=$(python3 "$src/scripts/check_citations" --root "$src" --also "$planted")
status=$?
echo "$out"
[ "$status" -eq 1 ] || { echo "expected exit 1, got $status"; exit 1; }
for want in "no section §42" "no section \"No such title\"" "$cls::NoSuchMember does not exist" "cites $spec"; do
  grep -qF "$want" <<< "$out" || { echo "missing: $want"; exit 1; }
done
[ "$(grep -c "$(basename "$planted")" <<< "$out")" -eq 4 ] || { echo "expected exactly the 4 planted lines"; exit 1; }
echo "citations_planted: all four planted citations were flagged"
