#!/usr/bin/env bash
# scripts/check_citations must fail on planted dangling citations: a section
# docs/model.md does not have, a title it does not have, a member function
# that does not exist, a citation of the spec the repository does not
# contain, a docs page that does not exist, a section another page does not
# have, and a Markdown link that leads nowhere. Each must be named. (The
# citations are assembled from parts so that this file itself passes the
# check.)
#   citations_planted.sh SOURCE_DIR
set -uo pipefail
src=$1
planted=$(mktemp --suffix=.cc)
page=$(mktemp --suffix=.md)
trap 'rm -f "$planted" "$page"' EXIT
doc="docs/model.md" cls="StepEngine" spec="SPEC" note="docs/notes/collisions.md" gone="docs/notes/no-such-note.md"
printf '// See %s §42 and %s, "No such title".\n// Set up in %s::NoSuchMember (%s §5).\n' \
  "$doc" "$doc" "$cls" "$spec" > "$planted"
printf '// As in %s, and in %s, "No such section".\n' "$gone" "$note" >> "$planted"
printf 'The [guide](%s).\n' "no-such-guide.md" > "$page"
out=$(python3 "$src/scripts/check_citations" --root "$src" --also "$planted" "$page")
status=$?
echo "$out"
[ "$status" -eq 1 ] || { echo "expected exit 1, got $status"; exit 1; }
for want in "no section §42" "no section \"No such title\"" "$cls::NoSuchMember does not exist" "cites $spec" \
  "$gone does not exist" "$note has no section \"No such section\"" "the link no-such-guide.md leads nowhere"; do
  grep -qF "$want" <<< "$out" || { echo "missing: $want"; exit 1; }
done
[ "$(grep -c "$(basename "$planted")" <<< "$out")" -eq 6 ] || { echo "expected exactly the 6 planted lines of the source"; exit 1; }
[ "$(grep -c "$(basename "$page")" <<< "$out")" -eq 1 ] || { echo "expected exactly the planted link"; exit 1; }
echo "citations_planted: all seven planted citations were flagged"
