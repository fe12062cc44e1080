#!/usr/bin/env bash
# Install the Debian packages the build, tests, benchmarks and demo need, if missing.
# As root it runs apt-get; otherwise it prints the exact command and fails.
set -euo pipefail
pkgs=(cmake make gcc libc6-dev libcmocka-dev pkg-config gcc-arm-none-eabi
      libnewlib-arm-none-eabi binutils-arm-none-eabi valgrind python3 python3-serial
      python3-pytest python3-matplotlib)
pkgs+=(qemu-system-arm) # the STM32 image under QEMU (tests/qemu_ping.py)
pkgs+=(cppcheck clang-tidy clang libclang-rt-14-dev llvm-14) # make lint; make fuzz (llvm-cov)
pkgs+=(python3-hypothesis)  # property tests of the SDK's parser (tools/python/tests)
pkgs+=(python3-aiohttp libjs-chart.js chromium chromium-driver python3-selenium) # servoctl studio and its browser tests
pkgs+=(socat gdb-multiarch) # make qemu (serial bridging) and debugging the image under QEMU
missing=()
for p in "${pkgs[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
echo "install-deps: missing Debian packages: ${missing[*]}"
if [ "$(id -u)" -ne 0 ]; then
    echo "install-deps: run as root:  apt-get update && apt-get install -y ${missing[*]}" >&2
    exit 1
fi
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq --no-install-recommends "${missing[@]}"
