#!/usr/bin/env bash
# `make install` contents: library, headers, pkg-config file and CMake package, each usable by a
# program outside the tree; and the examples (examples/*.c) built from it as a user builds them,
# through pkg-config, run, and what they print checked against what their method guarantees.
set -u
consph=$1 src=$2
build=$(dirname "$consph")
command -v pkg-config >/dev/null || { echo "pkg-config not installed: skipped"; exit 77; }
# A sanitizer-instrumented library cannot be linked by a plain program: nothing to learn there.
[ "${CONSPH_SANITIZED:-0}" = 1 ] && { echo "sanitizer build: skipped"; exit 77; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail=0
bad() { echo "FAIL: $*"; fail=1; }
cmake --install "$build" --prefix "$tmp/prefix" >"$tmp/install.log" 2>&1 || { cat "$tmp/install.log"; bad "cmake --install"; }
for f in include/consph/consph.h include/consph/ops.h include/consph/study.h bin/consph \
  share/doc/consph/LICENSE; do
  [ -e "$tmp/prefix/$f" ] || bad "not installed: $f"
done
ls "$tmp"/prefix/lib*/libconsph.a >/dev/null 2>&1 || bad "static library not installed"
ls "$tmp"/prefix/lib*/libconsph.so >/dev/null 2>&1 || bad "shared library not installed"
ls "$tmp"/prefix/share/consph/studies/*.study >/dev/null 2>&1 || bad "studies not installed"
cat >"$tmp/use.c" <<'C'
#include <consph/consph.h>
#include <stdio.h>
int main(void)
{
    consph_kernel k;
    if (consph_kernel_init(&k, CONSPH_KERNEL_CUBIC, 1, 1.0) != CONSPH_OK) return 1;
    printf("%.12f\n", consph_kernel_w(&k, 0.0)); /* sigma_1 = 2/3 */
    return 0;
}
C
pc=$(ls -d "$tmp"/prefix/lib*/pkgconfig | head -1)
PKG_CONFIG_PATH=$pc cc "$tmp/use.c" -o "$tmp/use_pc" $(PKG_CONFIG_PATH=$pc pkg-config --cflags --libs --static consph) \
  >"$tmp/cc.log" 2>&1 || { cat "$tmp/cc.log"; bad "compile with pkg-config"; }
[ "$(LD_LIBRARY_PATH=$(dirname "$pc") "$tmp/use_pc" 2>/dev/null)" = "0.666666666667" ] || bad "pkg-config program output"
mkdir -p "$tmp/proj"
cat >"$tmp/proj/CMakeLists.txt" <<'CM'
cmake_minimum_required(VERSION 3.16)
project(use C)
find_package(consph REQUIRED)
add_executable(use ../use.c)
target_link_libraries(use consph::consph)
CM
cmake -S "$tmp/proj" -B "$tmp/proj/b" -DCMAKE_PREFIX_PATH="$tmp/prefix" >"$tmp/cm.log" 2>&1 &&
  cmake --build "$tmp/proj/b" >>"$tmp/cm.log" 2>&1 || { cat "$tmp/cm.log"; bad "find_package(consph)"; }
[ "$("$tmp/proj/b/use" 2>/dev/null)" = "0.666666666667" ] || bad "CMake package program output"

# examples/density_gradient.c, with the build line of examples/README.md.
PKG_CONFIG_PATH=$pc cc -std=c11 -O2 "$src/examples/density_gradient.c" \
  $(PKG_CONFIG_PATH=$pc pkg-config --cflags --libs consph) -lm -o "$tmp/density_gradient" \
  >"$tmp/cc.log" 2>&1 || { cat "$tmp/cc.log"; bad "density_gradient: compile"; }
if LD_LIBRARY_PATH=$(dirname "$pc") "$tmp/density_gradient" >"$tmp/dg.out" 2>&1; then
  cat "$tmp/dg.out"
  val() { awk -v k="$1" '$1 == k { print $2 }' "$tmp/dg.out"; }
  within() { awk -v e="$1" -v lo="$2" -v hi="$3" 'BEGIN { exit !(e != "" && e + 0 >= lo && e + 0 < hi) }'; }
  # The corrected gradient of a linear field is exact to round-off; the Shepard-normalised one
  # is not on disordered particles; the interior summation density is near ρ0, not equal.
  within "$(val gradient_error)" 0 1e-12 || bad "gradient of a linear field not exact: $(val gradient_error)"
  within "$(val shepard_gradient_error)" 1e-4 1 || bad "Shepard-normalised gradient error $(val shepard_gradient_error)"
  within "$(val density_spread)" 1e-6 0.1 || bad "density spread $(val density_spread)"
  [ "$(val particles)" = 900 ] || bad "particles: $(val particles)"
else
  cat "$tmp/dg.out"
  bad "density_gradient: run"
fi
[ $fail = 0 ] && echo "cli_install: 1 passed, 0 failed" || echo "cli_install: 0 passed, 1 failed"
exit $fail
