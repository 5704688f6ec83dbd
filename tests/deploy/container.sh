#!/usr/bin/env bash
# deploy/container/Dockerfile, checked offline (no registry to pull debian:12 from here): the
# runtime stage installs a package for every shared library the three executables load
# directly (from their ELF NEEDED entries, resolved with ldd and dpkg -S on this Debian 12
# machine), every package it names exists in Debian, and the image runs as a non-root user with
# the server as its entrypoint.
set -euo pipefail
REPO="$(cd "$(dirname "$0")/../.." && pwd)"
BIN="$1"
DF="$REPO/deploy/container/Dockerfile"
fail() { echo "container: $*"; exit 1; }

runtime=$(sed -n '/# runtime-packages-begin/,/# runtime-packages-end/p' "$DF" | tr ' \\' '\n\n' | grep -E '^lib|^ca-certificates$' | sort -u)
[ -n "$runtime" ] || fail "no runtime package list between the markers"
# One apt-cache call for the whole list (it names each package it knows once per version).
known=$(apt-cache show $runtime 2> /dev/null | awk '/^Package:/ {print $2}' | sort -u)
for p in $runtime; do
  grep -qx "$p" <<< "$known" || fail "runtime package '$p' is not a Debian 12 package"
done
# Packages every Debian image has (Essential or required by them).
base="libc6 libgcc-s1"
for b in invr invr-server invr-worker; do
  [ -x "$BIN/$b" ] || fail "$BIN/$b not built"
  resolved=$(ldd "$BIN/$b")
  needed=$(objdump -p "$BIN/$b" | awk '/NEEDED/ {print $2}')
  # dpkg records a file under /lib or /usr/lib (merged /usr): every spelling of every library,
  # asked in one dpkg -S call.
  declare -A spellings=()
  queries=()
  for lib in $needed; do
    path=$(awk -v n="$lib" '$1 == n {print $3}' <<< "$resolved")
    [ -n "$path" ] || fail "$b: $lib does not resolve"
    real=$(readlink -f "$path")
    spellings[$lib]="$path $real ${real#/usr} $(dirname "$path")/$(basename "$real")"
    for q in ${spellings[$lib]}; do queries+=("$q"); done
  done
  owners=$(dpkg -S "${queries[@]}" 2> /dev/null || true)
  for lib in $needed; do
    pkg=""
    for q in ${spellings[$lib]}; do
      pkg=$(awk -v f="$q" -F': ' '$2 == f {print $1; exit}' <<< "$owners" | cut -d: -f1)
      [ -n "$pkg" ] && break
    done
    [ -n "$pkg" ] || fail "$b: no package owns $lib"
    if ! grep -qx "$pkg" <<< "$runtime" && ! grep -qw "$pkg" <<< "$base"; then
      fail "$b needs $lib from $pkg, which the runtime stage does not install"
    fi
  done
  unset spellings
done
grep -q '^FROM debian:12 AS build' "$DF" || fail "no debian:12 build stage"
grep -q '^FROM debian:12 AS runtime' "$DF" || fail "no debian:12 runtime stage"
grep -q 'deploy/setup.sh --build-only' "$DF" || fail "the build stage does not install through deploy/setup.sh --build-only"
user=$(awk '/^FROM .* AS runtime/ {r=1} r && /^USER / {print $2}' "$DF" | tail -1)
[ -n "$user" ] && [ "${user%%:*}" != 0 ] && [ "${user%%:*}" != root ] || fail "the runtime stage does not switch to a non-root user ($user)"
grep -q '^ENTRYPOINT \["invr-server"\]' "$DF" || fail "the entrypoint is not invr-server"
# The default command's flags exist.
for f in $(sed -n 's/^CMD \[\(.*\)\]/\1/p' "$DF" | tr ',' '\n' | tr -d ' "' | grep '^--'); do
  "$BIN/invr-server" --help | grep -q -- "$f" || fail "CMD uses $f, which invr-server does not have"
done
echo "container: ok ($(wc -w <<< "$runtime") runtime packages cover the executables' libraries)"
