#!/usr/bin/env bash
# The wheel works outside the checkout (#16): build it, install it into a fresh venv, and from an
# empty folder run `selfcal fk`, a short analytic `selfcal run` (12 poses) and `selfcal render`. The
# robot models and the shipped scenarios travel as package data (pyproject force-include -> selfcal/models). Needs only the
# package registry (or uv's cache) for the dependencies; about 10 s with a warm cache.
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$(pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

echo "== uv build --wheel"
uv build --wheel --quiet -o "$work/dist"
wheel=$(ls "$work"/dist/*.whl)
for d in models scenarios; do
    for f in $(cd "$d" && find . -type f | sed 's|^\./||'); do
        unzip -l "$wheel" "selfcal/$d/$f" >/dev/null || { echo "wheel lacks selfcal/$d/$f"; exit 1; }
    done
done
tops=$(unzip -Z1 "$wheel" | cut -d/ -f1 | grep -v '\.dist-info$' | sort -u)
[ "$tops" = selfcal ] || { echo "the wheel installs more than one top-level package: $tops"; exit 1; }
echo "== install into a fresh venv"
uv venv --quiet "$work/venv"
uv pip install --quiet --python "$work/venv" "$wheel"

mkdir "$work/empty"
cd "$work/empty"
echo "== selfcal fk (from an empty folder)"
"$work/venv/bin/selfcal" fk --joints 0,0,0,0,0 | tee fk.json
grep -q '"xyz_mm": \[541.25' fk.json
echo "== selfcal run (analytic, 12 poses)"
cat > quick.toml <<'TOML'
[noise]
render = false
[trajectory]
poses = 12
[validation]
poses = 5
TOML
"$work/venv/bin/selfcal" run quick.toml --out run
test -s run/calibration.json && test -s run/report.md
echo "== selfcal render (MuJoCo scene and marker textures from the package data)"
MUJOCO_GL=${MUJOCO_GL:-egl} "$work/venv/bin/selfcal" render --joints 38.15,-30,45,-63.54,0
test -s render/left.png && test -s render/right.png
echo "== selfcal scenarios; a shipped scenario by name, its board from the package data"
# the list read whole first (a `| grep -q` closes the pipe at the first match: a race under pipefail)
listed=$("$work/venv/bin/selfcal" scenarios)
grep -q '^mono-charuco ' <<<"$listed"
"$work/venv/bin/python" -c "from selfcal.config.scenario import load_scenario, scenario_board; print(scenario_board(load_scenario('mono-charuco')))"
# nothing of the checkout was used: the installed package is outside $repo
"$work/venv/bin/python" -c "import selfcal.robot.definition as r, sys; d = r.models_dir(); print('models:', d); sys.exit(str(d).startswith('$repo'))"
echo "wheel check ok"
