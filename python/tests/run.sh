#!/usr/bin/env bash
# The Python package's tests (.ci/run's "python" step; run from anywhere):
#   1. the reference venv (Pinocchio, numpy; tests/reference/requirements.txt) under the target
#      directory, created as tests/common/mod.rs creates it if the Rust tests have not yet;
#   2. <target>/python-venv: maturin, pytest and matplotlib (python/tests/requirements.txt), on the
#      reference venv's interpreter, seeing its packages through a .pth file;
#   3. `maturin develop --release`: the package built into that venv (cargo's target directory and
#      lock file are the workspace's, so the ribbon library already built is reused);
#   4. pytest python/tests, with the release `ribbon` binary for the CLI comparisons.
# Every step fails loudly; nothing is skipped.
set -euo pipefail
cd "$(dirname "$0")/../.."
root=$(pwd)
target=${CARGO_TARGET_DIR:-$root/target}
mkdir -p "$target"
reference=$target/reference-venv
venv=$target/python-venv
requirements=python/tests/requirements.txt

# 1. The reference venv, under the lock the Rust tests take (flock(2), as File::lock).
exec 9>"$target/reference-venv.lock"
flock 9
if ! cmp -s tests/reference/requirements.txt "$target/reference-venv.stamp" || [ ! -x "$reference/bin/python" ]; then
    echo "python tests: creating the reference venv $reference (once per target dir; under a minute)"
    rm -f "$target/reference-venv.stamp"
    rm -rf "$reference"
    "${RIBBON_PYTHON:-python3}" -m venv "$reference"
    "$reference/bin/python" -m pip install --disable-pip-version-check --no-input -r tests/reference/requirements.txt
    cp tests/reference/requirements.txt "$target/reference-venv.stamp.tmp"
    mv "$target/reference-venv.stamp.tmp" "$target/reference-venv.stamp"
fi
flock -u 9

# 2. The build venv, reinstalled when its requirements or the reference venv change.
reference_site=$("$reference/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
stamp_text="$(cat "$requirements")
reference site-packages: $reference_site"
if [ "$(cat "$venv.stamp" 2>/dev/null)" != "$stamp_text" ] || [ ! -x "$venv/bin/python" ]; then
    echo "python tests: creating $venv"
    rm -f "$venv.stamp"
    rm -rf "$venv"
    base_python=$("$reference/bin/python" -c 'import sys; print(sys._base_executable)')
    "$base_python" -m venv "$venv"
    venv_site=$("$venv/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
    # addsitedir, not a bare path: the reference venv's own .pth files (cmeel's, which put
    # Pinocchio on the path) are read too.
    echo "import site; site.addsitedir('$reference_site')" > "$venv_site/ribbon-reference-venv.pth"
    "$venv/bin/python" -m pip install --disable-pip-version-check --no-input -r "$requirements"
    printf '%s' "$stamp_text" > "$venv.stamp"
fi

# 3. The package, built in release into the venv.
started=$(date +%s)
VIRTUAL_ENV=$venv PATH="$venv/bin:$PATH" "$venv/bin/maturin" develop --release --manifest-path python/Cargo.toml
echo "python tests: maturin develop took $(( $(date +%s) - started )) s"

# 4. The tests (they compare with the release binary's files).
if [ ! -x "$target/release/ribbon" ]; then
    cargo build --release --bin ribbon
fi
RIBBON_BIN=$target/release/ribbon MPLBACKEND=Agg "$venv/bin/python" -m pytest python/tests "$@"
