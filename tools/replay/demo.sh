#!/usr/bin/env bash
# The README's main job: replay a bundled recorded dump through the library in stream order (push
# + step per row: the continuous calibrator as the MCU runs it), then as one batch (replay port ->
# calibrator -> heading), print both reports, and write the plot where matplotlib is present.
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
# 1. the firmware's loop: every row in file order through push + step (the continuous calibrator,
#    time-sliced solve), 14 steps per row = a 100 Hz control loop with this ~7 Hz sensor
spr=${MAGCAL_DEMO_STEPS_PER_ROW:-14}
echo "== stream replay (continuous calibrator, as the MCU runs it)"
"$bin" --stream --steps-per-row "$spr" "$dump"
"$bin" --stream --steps-per-row "$spr" --json --headings "$out/$stem.stream_headings.csv" "$dump" \
    > "$out/$stem.stream.json"
echo "stream report (JSON): $out/$stem.stream.json"
echo "stream per-row headings (trust, generation): $out/$stem.stream_headings.csv"
# 2. the same dump as one batch (every row offered to one run(), the offline view)
echo "== batch replay (one run() over the whole dump)"
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
