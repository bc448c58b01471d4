#!/usr/bin/env bash
# The README's two commands exactly as a new user types them on a fresh machine, then checks
# that they did what the README promises (run by .ci/run inside tools/ci/without_libcjson.sh):
#  - configure takes Unity 2.4.3 and cJSON from Debian's cjson source package, without an apt
#    warning on the screen;
#  - the main job prints the report and writes the JSON report, the per-row headings (the plot's
#    input), the flash record, and the plot where matplotlib exists;
#  - the test command runs (and passes) every replay test the build registers.
set -euo pipefail
cd "$(dirname "$0")/../.."
if [ -e build/host ]; then echo "readme_fresh: build/host exists: not a fresh checkout" >&2; exit 1; fi
log=$(mktemp -d)
fail() { echo "readme_fresh: FAIL: $*" >&2; exit 1; }

# ---- README "Main job"
( cmake --preset host && cmake --build build/host --target replay-demo ) 2>&1 | tee "$log/main.txt"
grep -q "Unity 2.4.3: Debian's cjson" "$log/main.txt" || fail "configure did not say it used Debian's Unity 2.4.3"
grep -q "magcal-replay: cJSON compiled from Debian's cjson" "$log/main.txt" || fail "cJSON fallback not used"
if grep -E "^(W|E): |configured multiple times|CMake Warning" "$log/main.txt"; then fail "warnings on the first screen"; fi
demo=build/host/tools/replay/demo
stem=lsm9ds1_pmodnav_driver_glitches
grep -q "status            ok" "$log/main.txt" || fail "no report with status ok on stdout"
grep -qE "^ +[0-9]+  adopted  ok" "$log/main.txt" || fail "the stream replay adopted no calibration"
/usr/bin/python3 - "$demo/$stem.stream.json" <<'PY' || fail "stream replay JSON"
import json, sys
d = json.load(open(sys.argv[1]))
assert d["rows"] == 303 and d["generation"] >= 1, d
assert any(e["event"] == "adopted" for e in d["events"]), d["events"]
PY
/usr/bin/python3 - "$demo/$stem.json" "$demo/$stem.headings.csv" "$demo/$stem.rec" <<'PY' || fail "main job outputs"
import csv, json, os, sys
rep = json.load(open(sys.argv[1]))
assert rep["status"] == "ok" and rep["n_used"] > 100, rep
rows = list(csv.DictReader(open(sys.argv[2])))
assert len(rows) == rep["n_rows"] and {"heading_deg", "outlier"} <= set(rows[0]), len(rows)
assert os.path.getsize(sys.argv[3]) == 96
print("readme_fresh: report ok, %d samples used, %d heading rows, 96-byte record" % (rep["n_used"], len(rows)))
PY
if /usr/bin/python3 -c "import matplotlib" 2>/dev/null; then
  [ -s "$demo/$stem.png" ] || fail "matplotlib present but no plot"
fi

# ---- README "Test command"
cmake --workflow --preset host 2>&1 | tee "$log/test.txt"
n_replay=$(ctest --test-dir build/host -N -L replay | sed -n 's/^Total Tests: //p')
n_passed=$(grep -cE "Test +#[0-9]+: replay_[a-z0-9_]+ \.+ +Passed" "$log/test.txt" || true)
n_skipped=$(grep -cE "Test +#[0-9]+: replay_[a-z0-9_]+ \.+\*+Skipped" "$log/test.txt" || true)
echo "readme_fresh: replay tests registered $n_replay, passed $n_passed, skipped $n_skipped"
[ "${n_replay:-0}" -ge 20 ] || fail "only ${n_replay:-0} replay tests registered"
[ $((n_passed + n_skipped)) -eq "$n_replay" ] || fail "not every replay test ran and passed"
grep -q "100% tests passed" "$log/test.txt" || fail "test command did not pass 100 %"
rm -rf "$log"
