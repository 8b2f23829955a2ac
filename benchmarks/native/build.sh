#!/usr/bin/env bash
# Build benchmarks/native/_coupled_check*.so against the pin/coal wheels' headers and
# libraries (cmeel.prefix in site-packages) and Eigen's headers from PyPI's cmeel-eigen,
# which no runtime wheel ships (installed with --target into EIGEN_DIR, default
# /tmp/openup-native-eigen, if it is not there). One g++ job, niced.
#
#   bash benchmarks/native/build.sh            # PYTHON=python by default
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
python="${PYTHON:-python}"
eigen_dir="${EIGEN_DIR:-/tmp/openup-native-eigen}"
prefix="$("$python" -c 'import cmeel; print(cmeel.__path__[0] + ".prefix")' 2>/dev/null ||
  "$python" -c 'import site; print(site.getsitepackages()[0] + "/cmeel.prefix")')"
if [ ! -d "$eigen_dir/cmeel.prefix/include/eigen3" ]; then
  "$python" -m pip install --quiet --no-deps --target "$eigen_dir" "cmeel-eigen>=3.4,<3.5"
fi
pyver="$("$python" -c 'import sys; print(f"{sys.version_info[0]}{sys.version_info[1]}")')"
suffix="$("$python" -c 'import sysconfig; print(sysconfig.get_config_var("EXT_SUFFIX"))')"
pyinc="$("$python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')"
out="$here/_coupled_check$suffix"
# The definitions of pinocchio's and coal's CMake targets (lib/cmake/*/…Targets.cmake):
# BOOST_MPL_LIMIT_* fix the joint variant's layout, which must match the wheel's.
defs=(
  -DBOOST_MPL_LIMIT_LIST_SIZE=30 -DBOOST_MPL_LIMIT_VECTOR_SIZE=30
  -DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS -DBOOST_FUSION_INVOKE_MAX_ARITY=12
  -DPINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION -DPINOCCHIO_WITH_COLLISION -DPINOCCHIO_WITH_HPP_FCL
  -DCOAL_BACKWARD_COMPATIBILITY_WITH_HPP_FCL -DCOAL_HAS_OCTOMAP -DCOAL_HAVE_OCTOMAP
  -DOCTOMAP_MAJOR_VERSION=1 -DOCTOMAP_MINOR_VERSION=10 -DOCTOMAP_PATCH_VERSION=0
  -DNDEBUG
)
nice -n 15 "${CXX:-g++}" -std=c++17 -O3 -ffp-contract=off -fPIC -shared -fvisibility=hidden \
  "${defs[@]}" \
  -isystem "$prefix/include" -isystem "$eigen_dir/cmeel.prefix/include/eigen3" -isystem "$pyinc" \
  "$here/coupled_check.cpp" -o "$out" \
  -L"$prefix/lib" -Wl,-rpath,"$prefix/lib" \
  -lpinocchio_collision -lpinocchio_default -lcoal "-lboost_python$pyver" \
  -Wl,--as-needed
echo "$out"
