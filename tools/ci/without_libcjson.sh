#!/usr/bin/env bash
# Run a command where Debian's libcjson-dev (and libcjson1) are really absent for CMake and the
# compiler: a private mount namespace (unshare -m, root) in which /usr/include/cjson is an empty
# tmpfs and the libcjson files of the multiarch library directory are overlay whiteouts. The
# system itself is not changed. CI uses it for the README's commands on a "fresh machine".
#   tools/ci/without_libcjson.sh CMD [ARGS...]
set -euo pipefail
if [ "${MAGCAL_IN_NS:-}" != 1 ]; then
  exec unshare -m --propagation private env MAGCAL_IN_NS=1 bash "$0" "$@"
fi
libdir=/usr/lib/$(gcc -print-multiarch 2>/dev/null || echo x86_64-linux-gnu)
if [ -d /usr/include/cjson ]; then mount -t tmpfs -o size=1m none /usr/include/cjson; fi
if ls "$libdir"/libcjson* "$libdir"/cmake/cJSON "$libdir"/pkgconfig/libcjson.pc > /dev/null 2>&1; then
  scratch=$(mktemp -d)
  mount -t tmpfs -o size=8m none "$scratch"
  mkdir -p "$scratch/up/cmake" "$scratch/up/pkgconfig" "$scratch/work"
  for f in "$libdir"/libcjson* "$libdir"/cmake/cJSON "$libdir"/pkgconfig/libcjson.pc; do
    [ -e "$f" ] || [ -L "$f" ] || continue
    mknod "$scratch/up/${f#"$libdir"/}" c 0 0          # overlayfs whiteout: the name is gone
  done
  if [ -n "${MAGCAL_NO_OVERLAY:-}" ] ||
     ! mount -t overlay overlay -o "lowerdir=$libdir,upperdir=$scratch/up,workdir=$scratch/work" "$libdir" 2>/dev/null; then
    # No overlayfs here: a tmpfs of symlinks to every entry but libcjson's, built aside and then
    # bound over the directory (the tools that build it need the real directory until then).
    mkdir -p "$scratch/orig" "$scratch/new"
    mount --bind "$libdir" "$scratch/orig"
    for e in "$scratch"/orig/* "$scratch"/orig/.[!.]*; do
      [ -e "$e" ] || [ -L "$e" ] || continue
      n=${e##*/}
      case "$n" in libcjson*|pkgconfig|cmake) continue ;; esac
      ln -s "$e" "$scratch/new/$n"
    done
    mkdir "$scratch/new/pkgconfig" "$scratch/new/cmake"
    for e in "$scratch"/orig/pkgconfig/*; do [ "${e##*/}" = libcjson.pc ] || ln -s "$e" "$scratch/new/pkgconfig/"; done
    for e in "$scratch"/orig/cmake/*; do [ "${e##*/}" = cJSON ] || ln -s "$e" "$scratch/new/cmake/"; done
    mount --bind "$scratch/new" "$libdir"
  fi
fi
# Prove it: nothing of libcjson is left where CMake, gcc or the loader would look.
if [ -e /usr/include/cjson/cJSON.h ] || ls "$libdir"/libcjson* > /dev/null 2>&1 ||
   [ -e "$libdir/pkgconfig/libcjson.pc" ] || [ -e "$libdir/cmake/cJSON" ]; then
  echo "without_libcjson: libcjson still visible" >&2
  exit 1
fi
echo "without_libcjson: libcjson-dev hidden (empty /usr/include/cjson, no $libdir/libcjson*)"
exec "$@"
