/* flash_sim.h - simulated STM32F1 flash (store, image slots and boot record, hal.h) on the
 * host: counts erases per page, and can cut the power at the Nth program or erase, leaving
 * the half-word torn or the page half-erased (bits in an undefined state) like a brown-out
 * does. After a cut every operation fails until flash_sim_power_on(). */
#ifndef FLASH_SIM_H
#define FLASH_SIM_H

#include <stdbool.h>
#include <stdint.h>

#include "hal.h"

enum flash_cut {
    FLASH_CUT_CLEAN, /* the cut operation did not happen at all */
    FLASH_CUT_DONE,  /* it completed, then the power went */
    FLASH_CUT_TORN,  /* a program left some bits programmed, an erase some bits erased */
};

/* Every page the core numbers (hal.h): the store and both slots, then the boot record. */
#define FLASH_SIM_PAGES (HAL_PAGE_BOOTREC + 1u)

struct flash_sim {
    uint8_t mem[FLASH_SIM_PAGES][HAL_FLASH_PAGE_BYTES]; /* store, both slots, boot record */
    uint32_t erases[FLASH_SIM_PAGES]; /* erase cycles per page */
    uint32_t writes[FLASH_SIM_PAGES]; /* erases and programs that reached each page (torn
                                       * ones too), ever: a page whose count is unchanged
                                       * holds what it held */
    uint32_t ops;                     /* programs + erases since power-on */
    uint32_t programs;                /* half-words programmed into the store's pages, ever
                                       * (power cycles too): the store's records */
    uint32_t cut_at;                  /* cut the power at this op (1-based); 0 = never */
    uint8_t cut_kind;                 /* enum flash_cut */
    bool powered;
    uint32_t rng;                     /* decides the undefined bits of a torn op */
};

/* A blank (erased) flash with power on and no cut planned. */
void flash_sim_init(struct flash_sim *f);

/* Power comes back: clear the cut, count ops from 0 again. */
void flash_sim_power_on(struct flash_sim *f);

const uint8_t *flash_sim_page(struct flash_sim *f, uint8_t p);
bool flash_sim_erase(struct flash_sim *f, uint8_t p);
bool flash_sim_program(struct flash_sim *f, uint8_t p, uint16_t off, uint16_t value);

#endif
