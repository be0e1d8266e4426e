#!/usr/bin/env bash
# The "Noetic's Python" platform: TIAGo robots run ROS Noetic on Ubuntu 20.04, whose Python is 3.8
# with numpy 1.17.4, scipy 1.3.3, matplotlib 3.1.2 and PyYAML 5.3.1 (apt), plus what the
# README's Noetic line installs with `pip3 install --user`. Without Ubuntu, this emulates it:
#   - a Python 3.8 (pyenv's, else python3.8 on PATH);
#   - a virtualenv with --system-site-packages holding focal's apt versions
#     (test/platforms/noetic-python.txt), standing for the system's python3;
#   - the README's own `pip3 install --user ...` line, run with that virtualenv's pip and
#     PYTHONUSERBASE inside the cache, standing for the user's ~/.local;
# then checks that pybullet imports beside numpy 1.17.4 (left at 1.17.4), runs the library tests
# (pytest -m "not ros": ROS itself is not here) and imports every module of src/tiago_nav.
# Ends with "N passed, M failed"; exits non-zero on any failure or when nothing ran.
#
# The environment is cached in ${TIAGO_NAV_PLATFORMS:-<repository>/.platforms}/noetic-python/ and
# rebuilt when the requirements file, this script or the README's Noetic pip line changes.
# Arguments are passed to pytest (e.g. -x, -k corridor).
set -euo pipefail

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
REQS="$HERE/noetic-python.txt"
CACHE="${TIAGO_NAV_PLATFORMS:-$ROOT/.platforms}/noetic-python"
VENV="$CACHE/venv"
RESULTS="$CACHE/results"
say() { echo "[noetic-python] $*"; }

# nothing from the calling shell: a sourced ROS workspace puts Debian's rospy (another Python's)
# on PYTHONPATH, and the emulated robot has no ROS here
unset PYTHONPATH PYTHONHOME PYTHONSTARTUP PYTHONNOUSERSITE PIP_USER PIP_TARGET PIP_PREFIX \
    PIP_REQUIRE_VIRTUALENV VIRTUAL_ENV ROS_PACKAGE_PATH ROS_DISTRO
export PYTHONUSERBASE="$CACHE/user"
export PYTHONDONTWRITEBYTECODE=1 PIP_DISABLE_PIP_VERSION_CHECK=1 MPLBACKEND=Agg

# --- Python 3.8 --------------------------------------------------------------------------------
PY=
pyenv_root=
if command -v pyenv >/dev/null 2>&1; then
    pyenv_root="$(pyenv root)"
elif [ -d "${PYENV_ROOT:-$HOME/.pyenv}/versions" ]; then
    pyenv_root="${PYENV_ROOT:-$HOME/.pyenv}"
fi
if [ -n "$pyenv_root" ]; then
    for p in "$pyenv_root"/versions/3.8*/bin/python3.8; do
        [ -x "$p" ] && PY="$p"          # the last, i.e. the newest 3.8.x by name
    done
fi
if [ -z "$PY" ] && command -v python3.8 >/dev/null 2>&1; then
    PY="$(command -v python3.8)"
fi
if [ -z "$PY" ]; then
    echo "[noetic-python] error: no Python 3.8 found (Noetic's Python). Install one, e.g." >&2
    echo "    pyenv install 3.8        (https://github.com/pyenv/pyenv), or" >&2
    echo "    apt-get install python3.8 python3.8-venv   (where the distribution has it)" >&2
    echo "then run this again." >&2
    exit 1
fi
say "python: $PY ($("$PY" -c 'import platform; print(platform.python_version())'))"

# --- the README's Noetic pip line --------------------------------------------------------------
# the one line of README.md that starts with `pip3 install --user`, without its trailing comment
mapfile -t lines < <(grep -E '^pip3 install --user ' "$ROOT/README.md" || true)
if [ "${#lines[@]}" -ne 1 ]; then
    echo "[noetic-python] error: README.md has ${#lines[@]} lines starting with" \
         "'pip3 install --user' (expected the Noetic one alone)" >&2
    exit 1
fi
PIP_LINE="$(sed -E 's/[[:space:]]+#.*$//' <<< "${lines[0]}")"

# --- the cached environment --------------------------------------------------------------------
stamp="$( { "$PY" -c 'import sys; print(sys.version)'; cat "$REQS" "${BASH_SOURCE[0]}";
            echo "$PIP_LINE"; } | sha256sum | cut -d' ' -f1)"
if [ "$(cat "$CACHE/stamp" 2>/dev/null || true)" != "$stamp" ]; then
    t0=$SECONDS
    say "building $CACHE"
    rm -rf "$CACHE"
    mkdir -p "$CACHE"
    "$PY" -m venv --system-site-packages "$VENV"
    # Noetic's system python3: focal's apt versions
    say "apt's part: $(grep -cE '^[A-Za-z]' "$REQS") packages from ${REQS#"$ROOT"/}"
    "$VENV/bin/python" -m pip install -q -r "$REQS"
    # the user's part: the README's own line, with pip3 the emulated system's pip
    pip3() { "$VENV/bin/python" -m pip "$@"; }
    say "user's part: $PIP_LINE"
    eval "$PIP_LINE"
    unset -f pip3
    echo "$stamp" > "$CACHE/stamp"
    say "built in $((SECONDS - t0)) s"
else
    say "cached environment: $CACHE"
fi
PYV="$VENV/bin/python"
"$PYV" -m pip freeze --all 2>/dev/null > "$CACHE/freeze.txt"
say "installed: $(tr '\n' ' ' < "$CACHE/freeze.txt")"

# --- what the README's line gave: pybullet beside numpy 1.17.4 ---------------------------------
"$PYV" - <<'EOF'
import sys
import numpy
want = '1.17.4'
if numpy.__version__ != want:
    sys.exit('[noetic-python] error: numpy is %s, not focal\'s %s: the pip line replaced it'
             % (numpy.__version__, want))
try:
    import pybullet
except ImportError as e:
    sys.exit('[noetic-python] error: import pybullet failed beside numpy %s: %s'
             % (numpy.__version__, e))
print('[noetic-python] numpy %s, pybullet imports (%s), pybullet.isNumpyEnabled() = %s'
      % (numpy.__version__, pybullet.__file__, pybullet.isNumpyEnabled()))
EOF

# --- the library tests (test_imports.py among them: every module imports, or is named as needing ROS)
mkdir -p "$RESULTS"
xml="$RESULTS/unit.xml"
rm -f "$xml"
say "pytest test/unit -m 'not ros'"
rc=0
(cd "$ROOT" && "$PYV" -m pytest test/unit -q -p no:cacheprovider -m 'not ros' -rfEs \
    --junitxml="$xml" "$@") || rc=$?

# --- N passed, M failed ------------------------------------------------------------------------
"$PYV" - "$ROOT" "$xml" "$rc" <<'EOF'
import os
import sys
root, xml, rc = sys.argv[1], sys.argv[2], int(sys.argv[3])
sys.path.insert(0, os.path.join(root, 'test'))
from run_all import junit_counts    # noqa: E402
if os.path.exists(xml):
    passed, failed, skipped, names = junit_counts(xml)
else:
    passed, failed, skipped, names = 0, 1, 0, ['pytest exited %d without results' % rc]
if rc not in (0, 5) and failed == 0:
    failed, names = failed + 1, names + ['pytest exited %d' % rc]
for n in names:
    print('FAILED %s' % n)
line = '%d passed, %d failed' % (passed, failed)
if skipped:
    line += ', %d skipped' % skipped
print(line)
sys.exit(0 if failed == 0 and passed > 0 else 1)
EOF
