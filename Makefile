# Two commands for a fresh machine: `make run` and `make test` (both set up first).
PY := .venv/bin/python
SCENE ?=
MPI ?= 1

.PHONY: setup run test bench clean
setup:
	@bash scripts/setup.sh

run: setup
	@if [ "$(MPI)" = "1" ]; then $(PY) -m app run --overwrite $(SCENE); \
	else mpirun --allow-run-as-root --oversubscribe -n $(MPI) $(PY) -m app run --overwrite $(SCENE); fi

test: setup
	@$(PY) -m pytest -q -p no:cacheprovider tests

bench: setup
	@$(PY) benchmarks/run_all.py

clean:
	rm -rf output/* meshes/*.msh
