#!/usr/bin/env bash
# clothbench_inspect FILE table against the table bench_integrators printed
# when it wrote FILE: equal line for line, apart from inspect's first line
# (file, creation time, commit) and bench_integrators' last lines ("results:",
# "ParaView:", "report:").
#   inspect_table_check.sh INSPECT_BINARY FILE.h5 PRINTED.txt
set -euo pipefail
inspect=$1 file=$2 printed=$3
diff <("$inspect" "$file" table | tail -n +2) <(grep -v '^results: \|^ParaView: \|^report: ' "$printed")
echo "inspect_table_check: $(wc -l < "$printed") printed lines reproduced from $file"
