# Sourced by the scripts: the environment a build of Mentalsim needs. Source it yourself
# (`. scripts/env.sh`) to run cargo by hand.
#
# - The virtual environment provides libtorch (PyTorch's wheel) to tch. It is a per-machine
#   cache like the target directory (PyTorch's wheels are 5 GB; one copy per clone filled CI's
#   disk). The clone's `.venv` is a symlink to it, so `.venv/bin/python` works everywhere. A
#   clone whose `.venv` is a real directory keeps using that one.
# - LIBTORCH_USE_PYTORCH makes torch-sys ask that Python where libtorch is. torch-sys only
#   checks that the variable is set, and reruns its build script when its value changes, so
#   we set it to the venv's path: a different venv gets torch-sys rebuilt against it instead
#   of linking against one that may no longer exist.
# - The build output lives outside the clone, in a per-machine cache, so RocksDB and the
#   libtorch glue are compiled once per machine rather than once per clone or CI run.
_ms_root="$(cd "$(dirname "${BASH_SOURCE[0]:-$0}")/.." && pwd)"
_ms_cache="${XDG_CACHE_HOME:-$HOME/.cache}/mentalsim"
if [ -d "$_ms_root/.venv" ] && [ ! -L "$_ms_root/.venv" ]; then
  export VIRTUAL_ENV="$_ms_root/.venv"
else
  export VIRTUAL_ENV="${MENTALSIM_VENV:-$_ms_cache/venv}"
fi
case ":$PATH:" in
  *":$VIRTUAL_ENV/bin:"*) ;;
  *) export PATH="$VIRTUAL_ENV/bin:$PATH" ;;
esac
export LIBTORCH_USE_PYTORCH="$VIRTUAL_ENV"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$_ms_cache/target}"
# - The C and C++ of the dependencies (RocksDB above all, then SQLite and the libtorch glue) are
#   compiled by clang, which setup installs for bindgen anyway: on 2 cores it compiles RocksDB's
#   sources at -O2 about a quarter faster than g++ does, the largest step of a fresh machine's
#   build (docs/operations.md). A CC or CXX already set is kept.
if command -v clang >/dev/null 2>&1 && command -v clang++ >/dev/null 2>&1; then
  export CC="${CC:-clang}" CXX="${CXX:-clang++}"
fi
# - The workspace's own crates compile through clippy's driver (rustc that also runs clippy's
#   lints), so the build that serves and tests is the lint pass too: scripts/test fails on any
#   warning it reports, where `cargo clippy` would check every dependency a second time (about
#   100 s on a fresh machine). Every script sets it alike, so their builds share all units.
if command -v clippy-driver >/dev/null 2>&1; then
  export RUSTC_WORKSPACE_WRAPPER="${RUSTC_WORKSPACE_WRAPPER:-clippy-driver}"
fi
# CI builds each clone once: incremental caches would only grow the shared target directory.
if [ "${CI:-}" = "true" ]; then export CARGO_INCREMENTAL=0; fi
unset _ms_root _ms_cache
