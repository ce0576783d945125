#!/usr/bin/env bash
# Installs what gcpipe needs from Debian 12 packages, builds it, then runs the sample job or the
# test suite. Idempotent: packages already installed are not fetched again, the build is
# incremental (ccache), outputs are overwritten.
#
#   bash .ci/setup.sh sample   # build, then gcpipe batch on the paper's slot at F3000 (no DDS setup)
#   bash .ci/setup.sh test     # build, then the whole CTest suite
set -euo pipefail
cd "$(dirname "$0")/.."

what="${1:-}"
case "$what" in sample|test|build) ;; *) echo "usage: bash .ci/setup.sh sample|test|build" >&2; exit 2 ;; esac

packages=(
  build-essential cmake ninja-build ccache clang libclang-rt-14-dev
  libeigen3-dev libyaml-cpp-dev libopencv-dev nlohmann-json3-dev
  libfastrtps-dev libfastcdr-dev fastddsgen fastdds-tools
  libgtest-dev libgmock-dev libbenchmark-dev
  libcli11-dev libpng-dev
  help2man  # the man page build/docs/gcpipe.1 (docs/CMakeLists.txt)
  linuxcnc-uspace  # rs274, LinuxCNC's interpreter: the oracle of tests/rs274_diff_test.cpp
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "== installing: ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# clang: the same compiler builds the libFuzzer target; ccache keeps rebuilds short, also across
# fresh clones at other paths (CCACHE_BASEDIR makes its keys relative to the checkout).
export CCACHE_BASEDIR="$PWD"
echo "== configure and build (build/)"
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER=clang++ >/dev/null
cmake --build build -j"$(nproc)"

case "$what" in
  sample)
    echo "== gcpipe batch samples/trochoid_slot_f3000.nc -o out/trochoid_slot_f3000"
    build/stages/cli/gcpipe batch samples/trochoid_slot_f3000.nc -o out/trochoid_slot_f3000
    echo "== compensated program: out/trochoid_slot_f3000/compensated.nc; report: out/trochoid_slot_f3000/report.txt"
    echo "== the figure: out/trochoid_slot_f3000/plots/contour_error.png (and toolpath, following_error, ik_*, trochoid_engagement)"
    ;;
  test)
    echo "== ctest"
    ctest --test-dir build --output-on-failure -j"$(nproc)"
    ;;
  build) ;;
esac
