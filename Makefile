# Front door. `make test` and `make demo` work on a fresh Debian machine: both install
# what is missing first (tools/install-deps.sh).
JOBS ?= $(shell nproc 2>/dev/null || echo 2)

.PHONY: all deps host stm32 test bench demo docs clean

all: host stm32

deps:
	@tools/install-deps.sh

host: deps
	cmake --preset host
	cmake --build --preset host -j $(JOBS)

stm32: deps
	cmake --preset stm32
	cmake --build --preset stm32 -j $(JOBS)

test: host stm32
	ctest --preset host -j $(JOBS)

bench: deps
	cmake --preset bench
	cmake --build --preset bench -j $(JOBS)
	tools/bench.sh build/bench

demo: host
	build/host/tools/demo

docs: host
	build/host/tools/regdoc > docs/registers.md

clean:
	rm -rf build
