#!/usr/bin/env bash
# Build the package's wheel with the compiled check inside, from a clean clone of this
# branch, in pip's isolated build environment (pip wheel --no-deps): hatchling swapped
# for scikit-build-core (packaging/pyproject-scikit-build.toml, packaging/CMakeLists.txt).
# Prints the wall time, the peak memory and the wheel's compiled module; leaves the
# clone and the wheel in a temporary folder (printed). One compile job, niced.
#
#   bash benchmarks/native/try_wheel.sh
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(git -C "$here" rev-parse --show-toplevel)"
branch="$(git -C "$repo" rev-parse --abbrev-ref HEAD)"
work="$(mktemp -d /tmp/openup-wheel.XXXXXX)"
git clone -q -b "$branch" "$repo" "$work/src"
cp "$here/packaging/CMakeLists.txt" "$work/src/CMakeLists.txt"
python - "$work/src/pyproject.toml" "$here/packaging/pyproject-scikit-build.toml" <<'PY'
import re
import sys

path, fragment = sys.argv[1], open(sys.argv[2]).read()
text = open(path).read()
build = re.search(r"\[build-system\]\n(?:[^\[\n].*\n)*", text)
hatch = re.search(r"\[tool\.hatch\.build\.targets\.wheel\]\n(?:.*\n)*?(?=\n\[tool\.pytest)", text)
if build is None or hatch is None:
    sys.exit("pyproject.toml: no [build-system] or hatchling wheel sections to replace")
sections = fragment.split("[tool.scikit-build]")
text = text.replace(hatch.group(0), "[tool.scikit-build]" + sections[1].rstrip("\n") + "\n")
text = text.replace(build.group(0), "[build-system]" + sections[0].split("[build-system]")[1].rstrip("\n") + "\n")
open(path, "w").write(text)
PY
export CMAKE_BUILD_PARALLEL_LEVEL=1
if /usr/bin/time -v nice -n 15 python -m pip wheel --no-deps "$work/src" -w "$work/wheel" \
  > "$work/pip.log" 2> "$work/time.log"; then
  echo "built: $(ls "$work"/wheel/*.whl)"
else
  echo "failed: see $work/time.log" >&2
fi
grep -E "Elapsed \(wall clock\)|Maximum resident" "$work/time.log"
python -m zipfile -l "$work"/wheel/*.whl 2>/dev/null | grep -E "_coupled_check|_data/robots/" | head -3
echo "in $work"
