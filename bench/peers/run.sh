#!/usr/bin/env bash
# Peers benchmark: NVIDIA Warp (CPU, f64, one thread) and Taichi (CPU, f64, two threads) on
# the same standard work and the same mesh files as `raisov bench`; checks the 5-digit
# agreement on the 1k and 10k boxes and prints raisov's throughput as a ratio to each peer.
#
# Usage: bench/peers/run.sh [--sizes 100k,1M] [--steps N]
# Creates bench/peers/.venv (git-ignored). A peer that cannot be installed is reported and
# skipped; the others still run.
set -uo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
VENV="$HERE/.venv"
SIZES="100k,1M"
EXTRA=()
while [ $# -gt 0 ]; do
  case "$1" in
    --sizes) SIZES="$2"; shift 2 ;;
    *) EXTRA+=("$1"); shift ;;
  esac
done

if [ ! -x "$VENV/bin/python" ]; then
  echo "== creating $VENV"
  python3 -m venv "$VENV" || { echo "ERROR: python3 -m venv failed"; exit 1; }
fi
echo "== installing numpy, warp-lang, taichi into $VENV"
"$VENV/bin/pip" install -q --upgrade pip >/dev/null 2>&1
"$VENV/bin/pip" install -q numpy || { echo "ERROR: numpy could not be installed"; exit 1; }
for pkg in warp-lang taichi; do
  if ! "$VENV/bin/pip" install -q "$pkg"; then
    echo "WARNING: $pkg could not be installed here; its rows will be skipped"
  fi
done

echo "== building raisov (release)"
(cd "$ROOT" && cargo build --release -q -p raisov-cli) || { echo "ERROR: cargo build failed"; exit 1; }
RAISOV="$ROOT/target/release/raisov"
MESHDIR="$HERE/meshes"
"$RAISOV" bench --write-mesh "$MESHDIR" --sizes "1k,10k,$SIZES" || exit 1

exec "$VENV/bin/python" "$HERE/peers.py" --raisov "$RAISOV" --meshes "$MESHDIR" --sizes "$SIZES" "${EXTRA[@]}"
