# The reference foot board: its MCU, which picks the linker script in board/.
set(BOARD_MCU stm32f103x8)
