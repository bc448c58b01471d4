#!/usr/bin/env bash
# Prepare a Unity source tree from Debian's cjson source package, which carries Unity 2.4.3 in
# tests/unity/. Uses a private apt state (no change to the system's apt configuration, no root
# needed): the deb-src entries are derived from the machine's own deb entries.
#   tools/get_unity.sh [DEST]      (default DEST: <repo>/.deps/unity)
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
dest=${1:-$here/.deps/unity}
if [ -f "$dest/src/unity.c" ]; then echo "get_unity: $dest already present"; exit 0; fi

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/lists/partial" "$work/archives/partial" "$work/src"

# Build a deb-src list from the configured deb sources (one-line and deb822 formats).
srclist="$work/sources.list"
: > "$srclist"
if [ -f /etc/apt/sources.list ]; then
  sed -n -E 's/^deb (\[[^]]*\] )?/deb-src \1/p' /etc/apt/sources.list >> "$srclist" || true
fi
for f in /etc/apt/sources.list.d/*.sources; do
  [ -f "$f" ] || continue
  awk '
    /^[[:space:]]*$/ { flush(); next }
    /^Types:/   { types=$0 }
    /^URIs:/    { sub(/^URIs:[[:space:]]*/, ""); uris=$0 }
    /^Suites:/  { sub(/^Suites:[[:space:]]*/, ""); suites=$0 }
    /^Components:/ { sub(/^Components:[[:space:]]*/, ""); comps=$0 }
    /^Signed-By:/ { sub(/^Signed-By:[[:space:]]*/, ""); key=$0 }
    function flush() {
      if (types ~ /deb/ && uris != "" && uris ~ /debian/) {
        n = split(suites, s, " ");
        for (i = 1; i <= n; i++) {
          opt = (key != "") ? "[signed-by=" key "] " : "";
          print "deb-src " opt uris " " s[i] " " comps
        }
      }
      types=""; uris=""; suites=""; comps=""; key=""
    }
    END { flush() }' "$f" >> "$srclist"
done
if [ ! -s "$srclist" ]; then echo "get_unity: no Debian sources configured" >&2; exit 1; fi

aptopts=(-o Dir::Etc::SourceList="$srclist" -o Dir::Etc::SourceParts=/nonexistent
         -o Dir::State::Lists="$work/lists" -o Dir::Cache::Archives="$work/archives"
         -o Debug::NoLocking=1 -o APT::Sandbox::User=root -qq)
apt-get "${aptopts[@]}" update
( cd "$work/src" && apt-get "${aptopts[@]}" source --download-only cjson )
tarball=$(ls "$work"/src/cjson_*.orig.tar.* | head -n 1)
mkdir -p "$work/x"
tar -xf "$tarball" -C "$work/x"
unity=$(find "$work/x" -type d -path '*/tests/unity' | head -n 1)
if [ ! -f "$unity/src/unity.c" ]; then echo "get_unity: no tests/unity in $tarball" >&2; exit 1; fi
mkdir -p "$(dirname "$dest")"
rm -rf "$dest"
cp -r "$unity" "$dest"
echo "get_unity: Unity $(cat "$dest/release/version.info" 2>/dev/null || echo '?') -> $dest"
