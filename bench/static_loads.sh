#!/usr/bin/env bash
# Static equilibrium of the pressure and probe examples at two mesh sizes (6³ and 16³ cubes),
# each by the assembled direct Newton (`solver = "direct"`) and by matrix-free Newton-Krylov
# (`solver = "krylov"`), side by side: each solver's own stopping rule, its summary lines
# (iterations, force evaluations, residual reached, wall time, reactions). Newton-Krylov is
# tuned by running it at its default 10 load increments and at 1 and 3: its figure is the
# fastest of those that converged.
# usage: bash bench/static_loads.sh [RAISOV_BINARY]   (default: target/release/raisov)
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-target/release/raisov}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for ex in pressure_block probe_block; do
    for d in 6 16; do
        for solver in direct krylov krylov-1 krylov-3; do
            f=$work/${ex}_${d}_$solver.toml
            # The dynamic example without its damping, on d³ cubes, solved statically.
            sed -e "s/divisions = \[6, 6, 6\]/divisions = [$d, $d, $d]/" \
                -e '/^\[damping\]/,/^$/d' "examples/$ex.toml" >"$f"
            printf '\n[integrator]\nmethod = "newton"\nsolver = "%s"\n' "${solver%%-*}" >>"$f"
            [[ $solver == *-* ]] && echo "increments = ${solver#*-}" >>"$f"
            echo "== $ex, ${d}x${d}x${d} cubes, $solver"
            "$bin" run --quiet --out "$work/out_${ex}_${d}_$solver" "$f" 2>&1 |
                grep -E '^(solve|stopped|newton steps|residual|force evals|wall time|reactions|tool contact|applied)' || true
        done
    done
done
