#!/usr/bin/env bash
# benchmarks/loop.py on two revisions in one session, interleaved (before, after, before, ...), so that
# both meet the same host: the loop's late-cycle figures before and after a change to the runtime.
#
#     benchmarks/loop_before_after.sh REV [ROUNDS] [DURATION_S]
#
# REV is checked out into a temporary git worktree (removed at the end); its own benchmarks/loop.py
# runs its own src/ (PYTHONPATH), against this checkout's. Issue 32 used REV = 1ba6dc8~1 (before
# ControlLoop._run was split into named steps).
set -euo pipefail
cd "$(dirname "$0")/.."
rev=${1:?usage: benchmarks/loop_before_after.sh REV [ROUNDS] [DURATION_S]}
rounds=${2:-3}
duration=${3:-20}
tree=$(mktemp -d)
trap 'git worktree remove --force "$tree"' EXIT
git worktree add -q --detach "$tree" "$rev"
for round in $(seq "$rounds"); do
    echo "== round $round: before ($rev)"
    PYTHONPATH="$tree/src" .venv/bin/python "$tree/benchmarks/loop.py" --duration "$duration" --rates 500 1000
    echo "== round $round: after (this checkout)"
    .venv/bin/python benchmarks/loop.py --duration "$duration" --rates 500 1000
done
