#!/usr/bin/env bash
# Prepare a Unity source tree from Debian's cjson source package, which carries Unity 2.4.3 in
# tests/unity/ (tools/get_debian_cjson.sh does the download: private apt state, no root, only
# Debian's archive). The configure step does this by itself in the build tree; this script is
# for a tree shared by several build directories or prepared before going offline.
#   tools/get_unity.sh [DEST]      (default DEST: <repo>/.deps/unity)
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
dest=${1:-$here/.deps/unity}
if [ -f "$dest/src/unity.c" ]; then echo "get_unity: $dest already present"; exit 0; fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
bash "$here/tools/get_debian_cjson.sh" "$work/cjson"
mkdir -p "$(dirname "$dest")"
rm -rf "$dest"
cp -r "$work/cjson/tests/unity" "$dest"
echo "get_unity: Unity $(cat "$dest/release/version.info" 2>/dev/null || echo '?') -> $dest"
