#!/usr/bin/env bash
# Unpack Debian's `cjson` source package (Debian's patches applied) into DEST. It carries both
# things the build may need from outside: the cJSON library source (cJSON.c, cJSON.h: the
# replay harness's fallback when libcjson-dev is not installed) and Unity 2.4.3 (tests/unity/).
# Uses a private apt state (no change to the system's apt configuration, no root needed): the
# deb-src entries are derived from the machine's own Debian deb entries, one per
# (URI, suite, component), so apt never sees an entry twice.
#   tools/get_debian_cjson.sh DEST
# Nothing it writes is ever committed: DEST is inside a build tree (or .deps/, git-ignored).
set -euo pipefail
dest=${1:?usage: get_debian_cjson.sh DEST}
if [ -f "$dest/cJSON.c" ] && [ -f "$dest/tests/unity/src/unity.c" ]; then
  echo "get_debian_cjson: $dest already present"
  exit 0
fi

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/lists/partial" "$work/archives/partial" "$work/src"

# deb-src lines from the configured Debian sources (one-line and deb822 formats), printed as
# "URI SUITE COMPONENTS|SIGNED-BY"; deduplicated below.
{
  for f in /etc/apt/sources.list /etc/apt/sources.list.d/*.list; do
    [ -f "$f" ] || continue
    awk '
      /^[[:space:]]*deb(-src)?[[:space:]]/ {
        i = 2; key = "";
        if ($2 ~ /^\[/) {          # options: [ signed-by=... arch=... ]
          while (i <= NF) {
            o = $i; gsub(/[][]/, "", o);
            if (o ~ /^signed-by=/) { sub(/^signed-by=/, "", o); key = o }
            if ($i ~ /\]$/) { i++; break }
            i++
          }
        }
        line = $i " " $(i + 1);
        for (j = i + 2; j <= NF; j++) line = line " " $j;
        print line "|" key
      }' "$f"
  done
  for f in /etc/apt/sources.list.d/*.sources; do
    [ -f "$f" ] || continue
    awk '
      function flush(   n, s, i) {
        if (types ~ /deb/ && uris != "" && enabled !~ /^[Nn]o/) {
          n = split(suites, s, " ");
          for (i = 1; i <= n; i++) print uris " " s[i] " " comps "|" key
        }
        types = ""; uris = ""; suites = ""; comps = ""; key = ""; enabled = ""
      }
      /^[[:space:]]*$/ { flush(); next }
      /^Types:/      { types = $0 }
      /^Enabled:/    { sub(/^Enabled:[[:space:]]*/, ""); enabled = $0 }
      /^URIs:/       { sub(/^URIs:[[:space:]]*/, ""); uris = $0 }
      /^Suites:/     { sub(/^Suites:[[:space:]]*/, ""); suites = $0 }
      /^Components:/ { sub(/^Components:[[:space:]]*/, ""); comps = $0 }
      /^Signed-By:/  { sub(/^Signed-By:[[:space:]]*/, ""); key = $0 }
      END { flush() }' "$f"
  done
} | awk -F'|' '
  # Debian archives only; one entry per (URI without trailing slash, suite, component).
  $1 ~ /debian/ {
    split($1, w, " "); uri = w[1]; sub(/\/+$/, "", uri);
    for (i = 3; i in w; i++) {
      k = uri " " w[2] " " w[i];
      if (!(k in seen)) { seen[k] = 1; opt = ($2 != "") ? "[signed-by=" $2 "] " : "";
                          print "deb-src " opt uri " " w[2] " " w[i] }
    }
  }' > "$work/sources.list"
if [ ! -s "$work/sources.list" ]; then
  echo "get_debian_cjson: no Debian sources configured in /etc/apt" >&2
  exit 1
fi

aptopts=(-o Dir::Etc::SourceList="$work/sources.list" -o Dir::Etc::SourceParts=/nonexistent
         -o Dir::State::Lists="$work/lists" -o Dir::Cache::Archives="$work/archives"
         -o Debug::NoLocking=1 -o APT::Sandbox::User="$(id -un)" -qq)
if ! apt-get "${aptopts[@]}" update; then
  echo "get_debian_cjson: apt-get update failed (is Debian's archive reachable?)" >&2
  exit 1
fi
( cd "$work/src" && apt-get "${aptopts[@]}" source --download-only cjson )
dsc=$(ls "$work"/src/cjson_*.dsc | head -n 1)
mkdir -p "$(dirname "$dest")"
rm -rf "$dest"
if command -v dpkg-source > /dev/null; then
  # apt checked the files against the signed index; --no-check as `apt-get source` itself does.
  dpkg-source -q --no-check -x "$dsc" "$dest" > /dev/null
else
  # No dpkg-dev: the upstream tarball plus Debian's patch series, applied with patch(1).
  mkdir -p "$work/x" "$dest"
  tar -xf "$(ls "$work"/src/cjson_*.orig.tar.* | head -n 1)" -C "$work/x"
  cp -r "$work"/x/*/. "$dest/"
  tar -xf "$(ls "$work"/src/cjson_*.debian.tar.* | head -n 1)" -C "$dest"
  if [ -f "$dest/debian/patches/series" ]; then
    while read -r p; do
      case "$p" in ''|'#'*) continue ;; esac
      patch -s -p1 -d "$dest" < "$dest/debian/patches/$p"
    done < "$dest/debian/patches/series"
  fi
fi
for f in cJSON.c cJSON.h tests/unity/src/unity.c; do
  if [ ! -f "$dest/$f" ]; then echo "get_debian_cjson: $dsc has no $f" >&2; exit 1; fi
done
ver=$(basename "$dsc" .dsc); ver=${ver#cjson_}
echo "$ver" > "$dest/.debian_version"
echo "get_debian_cjson: cjson $ver (cJSON + Unity $(cat "$dest/tests/unity/release/version.info" 2>/dev/null || echo '?')) -> $dest"
