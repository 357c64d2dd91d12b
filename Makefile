# One place for the commands CI runs. `make test` installs into .venv and runs every test;
# `make check` adds formatting, lints and the stub check (what .ci/run replays).
VENV   ?= .venv
PY     := $(VENV)/bin/python
BIN    := $(VENV)/bin

.PHONY: install test check lint demo bench docs clean

$(VENV)/bin/activate:
	python3 -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip

install: $(VENV)/bin/activate
	$(PY) -m pip install -q -e ".[test]"

test: install
	cargo test
	$(BIN)/pytest -q

lint: install
	cargo fmt --check
	cargo clippy --all-targets -- -D warnings
	cargo clippy --features python -- -D warnings
	$(BIN)/ruff check python tests examples bench
	$(BIN)/ruff format --check python tests examples bench
	$(BIN)/python -m mypy.stubtest kinema._kinema --allowlist .mypy-stubtest-allowlist
	$(BIN)/mypy python/kinema

check: lint test

demo: install
	$(BIN)/kinema demo

docs: install
	$(BIN)/mkdocs build --strict --site-dir site

bench: install
	$(PY) -m pip install -q -e ".[bench]"
	for f in bench/bench_*.py; do $(PY) $$f || exit 1; done

clean:
	rm -rf $(VENV) target kinema-out site
