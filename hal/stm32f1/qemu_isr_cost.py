#!/usr/bin/python3
"""qemu_isr_cost.py - instructions the firmware image executes per received byte: the
USART1 handler, servo_rx_isr(), hal_clock_us() and frame_rx_byte(), counted by
single-stepping the image under QEMU with gdb while a READ frame arrives.

Needs qemu-system-arm and gdb-multiarch (Debian packages; not part of make test).
Usage: qemu_isr_cost.py build/stm32/servo-arm.elf  (symbols from the application's ELF;
QEMU boots servo-arm-full.bin beside it: the bootloader starts the application)
"""
import os
import socket
import subprocess
import sys
import tempfile
import time

FRAME = bytes.fromhex("D55D010402000209")  # READ model number, 8 bytes


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def main(elf):
    full = elf[:-len(".elf")] + "-full.bin"
    nm = subprocess.run(["arm-none-eabi-nm", elf], check=True, capture_output=True,
                        text=True).stdout
    handler = next(int(l.split()[0], 16) for l in nm.splitlines()
                   if l.split()[-1] == "usart1_handler")
    # Stop at the first byte's handler, then single-step until thread mode, noting each
    # new entry into the handler (the bytes tail-chain: QEMU delivers the next one as
    # soon as DR is read).
    script = f"""set pagination off
target remote :{{port}}
break *0x{handler:08x}
continue
delete
set $n = 0
set $last = 0
set $b = 0
while $b < {len(FRAME)} && $n < 5000
  stepi
  set $n = $n + 1
  if $pc == 0x{handler:08x}
    printf "BYTE %d %d\\n", $b, $n - $last
    set $last = $n
    set $b = $b + 1
  end
  if ($xpsr & 0x1ff) == 0
    printf "BYTE %d %d\\n", $b, $n - $last
    set $b = 99
  end
end
kill
"""
    port, serial = free_port(), free_port()
    qemu = subprocess.Popen(["qemu-system-arm", "-M", "stm32vldiscovery", "-nographic",
                             "-monitor", "none", "-device",
                             f"loader,file={full},addr=0x08000000", "-gdb",
                             f"tcp:127.0.0.1:{port}", "-serial",
                             f"tcp:127.0.0.1:{serial},server=on,wait=off,nodelay=on"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        time.sleep(0.5)
        with tempfile.NamedTemporaryFile("w", suffix=".gdb", delete=False) as f:
            f.write(script.replace("{port}", str(port)))
        gdb = subprocess.Popen(["gdb-multiarch", "-q", "-batch", "-x", f.name, elf],
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        time.sleep(1.5)
        with socket.create_connection(("127.0.0.1", serial)) as s:
            s.sendall(FRAME)
            out = gdb.communicate(timeout=120)[0]
        os.unlink(f.name)
    finally:
        qemu.kill()
        qemu.wait()
    counts = [int(l.split()[2]) for l in out.splitlines() if l.startswith("BYTE")]
    if not counts or len(counts) > len(FRAME):
        print(out, file=sys.stderr)
        return 1
    total = sum(counts) + 1  # + the first handler instruction, where the break stopped
    print(f"Cortex-M3 instructions for the {len(FRAME)} bytes of a READ frame: {total}, "
          f"{total / len(FRAME):.0f} per received byte")
    print("  (handler, servo_rx_isr, hal_clock_us, frame_rx_byte; a SysTick tick nested "
          "in between is counted too)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
