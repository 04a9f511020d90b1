#!/usr/bin/env bash
# The Python client's checks (issue 18): mypy --strict on the package, the README's example and
# the tests; then pytest: the client against the committed OpenAPI documents, local policy
# inference, and every method against the real binary (tests/conftest.py starts `mentalsim
# serve`; the binary is MENTALSIM_BIN, else $CARGO_TARGET_DIR/release/mentalsim). Nothing is
# installed: the package is imported from src/ (PYTHONPATH). Arguments go to pytest (`-k plan`).
set -euo pipefail
cd "$(dirname "$0")"
python="${PYTHON:-python}"
export PYTHONPATH="$PWD/src${PYTHONPATH:+:$PYTHONPATH}"
# The package must pass; its example and tests are held to the same standard.
"$python" -m mypy --strict src/mentalsim_client examples/plan.py
PYTHONPATH="$PWD/tests:$PYTHONPATH" "$python" -m mypy --strict tests
"$python" -m pytest -rs "$@"
