#!/usr/bin/env bash
# The README's main job: replay a bundled recorded dump through the library (replay port ->
# calibrator -> heading), print the report, and write the plot where matplotlib is present.
#   tools/replay/demo.sh MAGCAL_REPLAY_BIN OUT_DIR [DUMP.csv]
set -euo pipefail
bin=$1
out=$2
root=$(cd "$(dirname "$0")/../.." && pwd)
dump=${3:-$root/tests/data/real/lsm9ds1_pmodnav_driver_glitches.csv}
# the bundled LSM9DS1 dump is in gauss (its README): say so, and the report and plot carry it
unit=()
if [ -z "${3:-}" ]; then unit=(--field-unit gauss); fi
mkdir -p "$out"
stem=$(basename "$dump" .csv)
"$bin" "${unit[@]}" "$dump"
"$bin" --json "${unit[@]}" --headings "$out/$stem.headings.csv" "$dump" > "$out/$stem.json"
echo "report (JSON): $out/$stem.json"
echo "per-row headings: $out/$stem.headings.csv"
"$bin" --export-record "$out/$stem.rec" "$dump" > /dev/null
echo "flash record (magcal/record.h, 96 bytes): $out/$stem.rec"
if /usr/bin/python3 -c "import matplotlib" 2>/dev/null; then
  /usr/bin/python3 "$root/tools/plot_replay.py" "$dump" --headings "$out/$stem.headings.csv" \
      --report "$out/$stem.json" -o "$out/$stem.png"
  echo "plot: $out/$stem.png"
else
  echo "plot skipped: /usr/bin/python3 has no matplotlib (apt-get install python3-matplotlib)"
fi
