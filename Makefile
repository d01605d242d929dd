# Set-up is a stamp file: it is rebuilt only when pyproject.toml, setup.py or a compiled kernel's source changes,
# so repeat runs skip installs.
PY      := .venv/bin/python
STAMP   := .venv/.ld3-installed
OUT     ?= runs/demo

.PHONY: demo test lint bench clean

$(PY):
	python3 -m venv .venv

KERNELS := $(wildcard tracks/*.pyx tracks/*.pxd vehicles/*.pyx testbed/*.pyx testbed/*.h testbed/*/*.pyx \
                       testbed/*/*.pxd testbed/*/*/*.pyx)

$(STAMP): pyproject.toml setup.py $(KERNELS) | $(PY)
	$(PY) -m pip install --quiet torch==2.13.0
	$(PY) -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	.venv/bin/ld3 demo --out $(OUT)

test: $(STAMP)
	$(PY) -m pytest -q

lint: $(STAMP)
	.venv/bin/ruff check .

clean:
	rm -rf .venv runs .pytest_cache .ruff_cache
