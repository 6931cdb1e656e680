# Two commands for a fresh machine: `make run` and `make test` (both set up first).
PY := .venv/bin/python
SCENE ?=
MPI ?= 1

.PHONY: setup run test bench clean sweep lock docs instances
setup:
	@bash scripts/setup.sh

run: setup
	@if [ "$(MPI)" = "1" ]; then $(PY) -m app run --overwrite $(SCENE); \
	else mpirun --allow-run-as-root --oversubscribe -n $(MPI) $(PY) -m app run --overwrite $(SCENE); fi

test: setup
	@$(PY) -m pytest -q -p no:cacheprovider -n auto --dist worksteal tests

# Refresh requirements.lock from pyproject.toml (UPGRADE=1: newest versions that fit), then set up
lock: setup
	@UPGRADE=$(UPGRADE) bash scripts/lock.sh
	@bash scripts/setup.sh

# The documentation site (mkdocs.yml, docs/) into site/, warnings as errors
docs: setup
	@$(PY) -m mkdocs build --strict --quiet --site-dir site

bench: setup
	@bash scripts/setup_bench.sh
	@$(PY) benchmarks/run_all.py $(BENCH_ARGS)

# The library of certified MCEIP-mu instances (docs/instances.md) into output/instances/
instances: setup
	@$(PY) scripts/instance_library.py -o output/instances

# Parameter sweep as an MPI task farm (app/study/sweep.py): make sweep [SWEEP=file.yaml] [SWEEP_MPI=n]
SWEEP ?= app/scenes/sweep_aspect_ratio.yaml
SWEEP_MPI ?= 2
sweep: setup
	@mpirun --allow-run-as-root --oversubscribe -n $(SWEEP_MPI) $(PY) -m app run $(SWEEP)

clean:
	rm -rf output/* meshes/*.msh meshes/*.npz
