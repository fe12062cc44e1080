# Front door. `make test` and `make demo` work on a fresh Debian machine: both install
# what is missing first (tools/install-deps.sh).
JOBS ?= $(shell nproc 2>/dev/null || echo 2)

.PHONY: all deps host stm32 qemu qemu-image test lint fuzz bench demo demo-bytes docs clean \
	firmware flash studio boards

# Firmware images: every reference board (board/<name>/, listed once in
# cmake/boards.cmake), or the one `make flash` writes.
BOARDS := $(shell sed -n 's/^set(SERVO_BOARDS \(.*\))$$/\1/p' cmake/boards.cmake)
BOARD ?= arm
PORT ?= /dev/ttyUSB0
fw_build = { test -f build/stm32-$(1)/CMakeCache.txt || cmake -S . -B build/stm32-$(1) \
	--toolchain cmake/arm-none-eabi.cmake -DBOARD=$(1) -DCMAKE_BUILD_TYPE=MinSizeRel \
	>/dev/null; } && cmake --build build/stm32-$(1) -j $(JOBS) -- --no-print-directory

all: host stm32

deps:
	@tools/install-deps.sh

host: deps
	cmake --preset host
	cmake --build --preset host -j $(JOBS)

stm32: deps
	cmake --preset stm32
	cmake --build --preset stm32 -j $(JOBS)

# The arm for QEMU (preset qemu: plant model and RAM flash in place of motor and flash
# controller): build/qemu/servo-qemu-full.bin and servo-qemu.elf. `make qemu` boots it on
# qemu-system-arm -M stm32vldiscovery, USART1 on a TCP port, until Ctrl-C.
qemu-image: deps
	cmake --preset qemu
	cmake --build --preset qemu -j $(JOBS)

qemu: qemu-image
	@/usr/bin/python3 tools/qemu_servo.py

# ctest -j: JOBS CPU-bound tests at most (the preset's ctest-cpus.json, tests/CMakeLists.txt),
# and four more that mostly wait (the Python suites) beside them.
test: host stm32 qemu-image firmware lint
	ctest --preset host -j $$(( $(JOBS) + 4 ))

# Static analysis, zero findings (docs/lint.md): cppcheck + MISRA addon, clang-tidy,
# gcc -fanalyzer. About 30 s.
lint: host
	@tools/lint/lint.sh

# Every fuzz target (tests/fuzz/: fuzz_frame, fuzz_store, fuzz_update, fuzz_planner and
# the whole-servo fuzz_bus) under libFuzzer (clang, ASan+UBSan) for FUZZ_SECONDS each, a
# target per core, then the coverage of src/ by the merged corpora. CI runs a bounded
# session (FUZZ_SECONDS=20) before make test.
FUZZ_SECONDS ?= 600
fuzz: deps
	@FUZZ_SECONDS=$(FUZZ_SECONDS) tools/fuzz/fuzz.sh

# build/stm32-<board>/: servo-<board>.{elf,bin,hex,map} (the application; its .bin is the
# update file), servo-boot-<board>.* (the bootloader), servo-<board>-full.{bin,hex} (both,
# for a first flashing). The build fails past a budget.
size_table = awk '{ printf "%-12s %7d  %6.1f%%    %6d  %6.1f%%    (%d + %d + %d + %d)\n", \
	$$1, $$2, 100 * $$2 / $$8, $$3, 100 * $$3 / $$9, $$4, $$5, $$6, $$7 }'
firmware: deps
	@for b in $(BOARDS); do $(call fw_build,$$b) || exit 1; done
	@echo
	@echo "application  flash B  of 26 KiB-4 (goal 16 KiB = 16384 B: the build fails past it)  RAM B  of 6 KiB   (vectors + code/data + bss + stack)"
	@for b in $(BOARDS); do cat build/stm32-$$b/servo-$$b.size; done | $(size_table)
	@echo "bootloader   flash B  of 7 KiB (goal 5.5 KiB = 5632 B: the build fails past it)"
	@for b in $(BOARDS); do cat build/stm32-$$b/servo-boot-$$b.size; done | $(size_table)
	@echo
	@echo "worst-case stack per entry point (-fstack-usage + call graph; budget 75% of reserved)"
	@for b in $(BOARDS); do echo "$$b application"; cat build/stm32-$$b/servo-$$b.stack; \
	    echo "$$b bootloader"; cat build/stm32-$$b/servo-boot-$$b.stack; done

# Write BOARD's bootloader and application (servo-<board>-full.bin) over the STM32 serial
# bootloader (BOOT0 high, then reset): the wiring is in board/README.md. Erases the
# bootloader and both slots (60 pages: nothing an earlier update left in the staging slot
# can then be installed over the new application); the store's 4 pages at the top of
# flash keep the servo's settings.
flash: deps
	@$(call fw_build,$(BOARD))
	@img=build/stm32-$(BOARD)/servo-$(BOARD)-full.bin; \
	cmd="stm32flash -b 115200 -e 60 -w $$img -v -g 0x08000000 $(PORT)"; \
	echo "$$cmd"; \
	command -v stm32flash >/dev/null || { echo "make flash: stm32flash is not" \
	    "installed (Debian: apt-get install stm32flash)" >&2; exit 1; }; \
	[ -c "$(PORT)" ] || { echo "make flash: no serial port $(PORT): plug in the" \
	    "USB-UART adapter or give PORT=/dev/ttyUSBn" >&2; exit 1; }; \
	$$cmd

bench: deps qemu-image
	cmake --preset bench
	cmake --build --preset bench -j $(JOBS)
	tools/bench.sh build/bench

# The main job on the virtual servo bus: servo-sim + the Python SDK, in real time
# (about 25 s), writing build/demo.png. `make demo-bytes` shows the same bus byte by byte
# in virtual time.
# QEMU=1: the same session against the arm firmware under QEMU (make qemu's image).
demo: host $(if $(QEMU),qemu-image)
	/usr/bin/python3 tools/demo.py $(if $(QEMU),--qemu) build/demo.png

# Servo Studio in the browser on servo-sim with an arm, a foot and a base: prints the
# address to open (docs/studio.md). Ctrl-C stops both.
STUDIO_LISTEN ?= 127.0.0.1:8080
studio: host
	@PYTHONPATH=tools/python /usr/bin/python3 -m servobus.studio.onsim build/host/servo-sim \
	    --listen $(STUDIO_LISTEN)

demo-bytes: host
	build/host/tools/demo

docs: host
	/usr/bin/python3 tools/boards.py header > include/board_list.h
	build/host/tools/regdoc > docs/registers.md
	build/host/tools/regdoc --json > tools/python/servobus/registers.json
	build/host/tools/regdoc --protocol-json > tools/python/servobus/protocol.json

# The boards make firmware builds (CTest boards.list compares them with the list).
boards:
	@echo $(BOARDS)

clean:
	rm -rf build
