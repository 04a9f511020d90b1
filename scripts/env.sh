# Sourced by the scripts: the environment a build of Mentalsim needs. Source it yourself
# (`. scripts/env.sh`) to run cargo by hand.
#
# - The project-local virtual environment provides libtorch (PyTorch's wheel) to tch.
# - LIBTORCH_USE_PYTORCH makes torch-sys ask that Python where libtorch is. torch-sys only
#   checks that the variable is set, and reruns its build script when its value changes, so
#   we set it to the venv's path: a clone in another directory gets torch-sys rebuilt against
#   its own venv instead of linking against a venv that may no longer exist.
# - The build output lives outside the clone, in a per-machine cache, so RocksDB and the
#   libtorch glue are compiled once per machine rather than once per clone or CI run.
_ms_root="$(cd "$(dirname "${BASH_SOURCE[0]:-$0}")/.." && pwd)"
export VIRTUAL_ENV="$_ms_root/.venv"
case ":$PATH:" in
  *":$VIRTUAL_ENV/bin:"*) ;;
  *) export PATH="$VIRTUAL_ENV/bin:$PATH" ;;
esac
export LIBTORCH_USE_PYTORCH="$VIRTUAL_ENV"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-${XDG_CACHE_HOME:-$HOME/.cache}/mentalsim/target}"
unset _ms_root
