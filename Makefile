# Two commands for a fresh machine: `make run` and `make test` (both set up first).
PY := .venv/bin/python
SCENE ?=
MPI ?= 1

.PHONY: setup run test bench clean sweep
setup:
	@bash scripts/setup.sh

run: setup
	@if [ "$(MPI)" = "1" ]; then $(PY) -m app run --overwrite $(SCENE); \
	else mpirun --allow-run-as-root --oversubscribe -n $(MPI) $(PY) -m app run --overwrite $(SCENE); fi

test: setup
	@$(PY) -m pytest -q -p no:cacheprovider tests

bench: setup
	@bash scripts/setup_bench.sh
	@$(PY) benchmarks/run_all.py $(BENCH_ARGS)

# Parameter sweep as an MPI task farm (app/sweep.py): make sweep [SWEEP=file.yaml] [SWEEP_MPI=n]
SWEEP ?= app/scenes/sweep_aspect_ratio.yaml
SWEEP_MPI ?= 2
sweep: setup
	@mpirun --allow-run-as-root --oversubscribe -n $(SWEEP_MPI) $(PY) -m app run $(SWEEP)

clean:
	rm -rf output/* meshes/*.msh meshes/*.npz
