#!/usr/bin/env bash
# The Python client's checks (issue 18): mypy --strict on the package, the README's example and
# the tests; then pytest: the client against the committed OpenAPI documents, local policy
# inference, and every method against the real binary (tests/conftest.py starts `mentalsim
# serve` through the repository's tests/support/mentalsim_service.py, as its other Python suites
# do; the binary is MENTALSIM_BIN, else $CARGO_TARGET_DIR/release/mentalsim). Nothing is
# installed: the package is imported from src/ and that module from ../../tests/support
# (PYTHONPATH). Arguments go to pytest (`-k plan`).
set -euo pipefail
cd "$(dirname "$0")"
python="${PYTHON:-python}"
export PYTHONPATH="$PWD/src${PYTHONPATH:+:$PYTHONPATH}"
support="$(cd ../../tests/support && pwd)"
# The package must pass; its example and tests are held to the same standard.
"$python" -m mypy --strict src/mentalsim_client examples/plan.py
# The support module is checked with them: on MYPYPATH (on PYTHONPATH mypy would take it for an
# installed package and skip its errors).
PYTHONPATH="$PWD/tests:$PYTHONPATH" MYPYPATH="$support" "$python" -m mypy --strict tests
PYTHONPATH="$support:$PYTHONPATH" "$python" -m pytest -rs "$@"
