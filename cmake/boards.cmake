# The reference boards, once: each has its folder board/<name>/ (board.c: its struct
# board; board_pins.h: its fittings; board.cmake: its MCU). Everything that goes over
# every board takes this list: the Makefile's BOARDS (make firmware), the firmware
# build's check of BOARD, the generated include/board_list.h (BOARD_COUNT and the boards
# of board_all[], which every per-board test and fuzzer iterates), tools/fuzz_seeds.py. Adding a board
# is its folder plus its name here, then `make docs` (CTest boards.list fails until the
# two agree and the header is regenerated). The order is the boards' index everywhere.
set(SERVO_BOARDS base foot arm wrist finger)
