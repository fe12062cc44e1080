/* regdoc.c - print the register reference (Markdown) from the control table itself, so
 * the docs can never disagree with the firmware. Usage: regdoc > docs/registers.md
 * With --json it prints the same table as JSON for the host tools
 * (regdoc --json > tools/python/servobus/registers.json; a CTest checks the copy); with
 * --protocol-json the instruction table (protocol_json.c). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "board.h"
#include "link.h"
#include "regdoc.h"
#include "regs.h"
#include "write.h"

/* The reference board of each variant: the first of board_all with that variant (the
 * register table's columns are variants, not boards). */
static const struct board *variant_board(int v)
{
    for (uint32_t i = 0; i < BOARD_COUNT; i++)
        if (board_all[i]->variant == v)
            return board_all[i];
    fprintf(stderr, "regdoc: no board of variant %d in cmake/boards.cmake\n", v);
    exit(1);
}
static const char variant_letter[VARIANT_COUNT] = {'B', 'F', 'A', 'W', 'H'};

static const char *unit_text(uint8_t unit)
{
    switch (unit) {
    case REG_UNIT_POSITION: return "position unit (reg 13 x 0.1 deg)";
    case REG_UNIT_SPEED: return "position units/s, signed";
    case REG_UNIT_DIR_SPEED: return "bit 15 direction (1 = negative), bits 0-14 position units/s";
    case REG_UNIT_ACCEL: return "10 deg/s^2";
    case REG_UNIT_DELAY: return "500 us";
    case REG_UNIT_CURRENT: return "0.1 A";
    case REG_UNIT_TEMP: return "deg C, bit 7 = sign";
    case REG_UNIT_RES: return "0.1 deg";
    default: return "";
    }
}

static void print_defaults(uint8_t addr)
{
    const struct reg_desc *d = &regs_table[addr];
    if (d->access == REG_ACCESS_W) {
        printf("-");
        return;
    }
    /* One value if every applicable variant agrees, else one per variant. */
    int first = -1, same = 1;
    for (int v = 0; v < VARIANT_COUNT; v++) {
        if (!regs_applicable(variant_board(v), addr))
            continue;
        int def = regs_default(variant_board(v), addr);
        if (first < 0)
            first = def;
        else if (def != first)
            same = 0;
    }
    if (same) {
        printf("%d", first);
        return;
    }
    const char *sep = "";
    for (int v = 0; v < VARIANT_COUNT; v++) {
        if (!regs_applicable(variant_board(v), addr))
            continue;
        printf("%s%c: %u", sep, variant_letter[v], (unsigned)regs_default(variant_board(v), addr));
        sep = ", ";
    }
}

static const char *unit_key(uint8_t unit)
{
    switch (unit) {
    case REG_UNIT_POSITION: return "position";
    case REG_UNIT_SPEED: return "speed";
    case REG_UNIT_DIR_SPEED: return "dir_speed";
    case REG_UNIT_ACCEL: return "accel";
    case REG_UNIT_DELAY: return "delay";
    case REG_UNIT_CURRENT: return "current";
    case REG_UNIT_TEMP: return "temperature";
    case REG_UNIT_RES: return "resolution";
    default: return 0;
    }
}

void regdoc_json_str(const char *s)
{
    putchar('"');
    for (; *s; s++) {
        if (*s == '"' || *s == '\\')
            printf("\\%c", *s);
        else if ((unsigned char)*s < 0x20)
            printf("\\u%04x", (unsigned)(unsigned char)*s);
        else
            putchar(*s);
    }
    putchar('"');
}

/* The table, the variants and the baud codes as one JSON document. */
static int print_json(void)
{
    printf("{\n  \"generator\": \"regdoc --json (from src/regs.c; do not edit)\",\n"
           "  \"table_size\": %u,\n  \"variants\": [\n", REGS_SIZE);
    for (int v = 0; v < VARIANT_COUNT; v++) {
        const struct board *b = variant_board(v);
        printf("    {\"name\": \"%s\", \"letter\": \"%c\", \"model_number\": %u, "
               "\"default_baud\": %u, \"return_delay\": %u, \"max_angle_ddeg\": %u, "
               "\"photo_switches\": %s}%s\n",
               b->name, variant_letter[v], b->model_number, (unsigned)b->default_baud,
               b->return_delay, b->max_angle_ddeg, b->photo_switches ? "true" : "false",
               v + 1 < VARIANT_COUNT ? "," : "");
    }
    /* Every board of the one list (a variant may have several), for the SDK's model
     * numbers: a board it does not list is a servo it does not know. */
    printf("  ],\n  \"boards\": [\n");
    for (uint32_t i = 0; i < BOARD_COUNT; i++)
        printf("    {\"name\": \"%s\", \"variant\": \"%s\", \"model_number\": %u}%s\n",
               board_all[i]->name, variant_board(board_all[i]->variant)->name,
               board_all[i]->model_number, i + 1u < BOARD_COUNT ? "," : "");
    printf("  ],\n  \"baud_rates\": [");
    for (uint8_t c = 1; c <= 10; c++)
        printf("%s%u", c > 1 ? ", " : "", (unsigned)link_baud(&board_arm, c));
    printf("],\n  \"units\": {");
    const char *sep = "";
    for (uint8_t u = REG_UNIT_POSITION; u <= REG_UNIT_RES; u++) {
        printf("%s\n    ", sep);
        regdoc_json_str(unit_key(u));
        printf(": ");
        regdoc_json_str(unit_text(u));
        sep = ",";
    }
    printf("\n  },\n  \"registers\": [\n");
    sep = "";
    for (uint8_t a = 0; a < REGS_SIZE; a++) {
        const struct reg_desc *d = &regs_table[a];
        if (!d->size)
            continue;
        printf("%s    {\"address\": %u, \"name\": ", sep, a);
        regdoc_json_str(d->name);
        printf(", \"size\": %u, \"access\": \"%s\", \"area\": \"%s\",\n", d->size,
               d->access == REG_ACCESS_R ? "R" : d->access == REG_ACCESS_W ? "W" : "RW",
               d->area == REG_AREA_EE ? "EEPROM" : "RAM");
        printf("     \"variants\": [");
        const char *vsep = "";
        for (int v = 0; v < VARIANT_COUNT; v++)
            if (d->variants & REG_V(v)) {
                printf("%s\"%s\"", vsep, variant_board(v)->name);
                vsep = ", ";
            }
        printf("], \"default\": {");
        vsep = "";
        for (int v = 0; v < VARIANT_COUNT; v++) {
            if (!regs_applicable(variant_board(v), a))
                continue;
            printf("%s\"%s\": ", vsep, variant_board(v)->name);
            if (d->access == REG_ACCESS_W)
                printf("null");
            else
                printf("%u", (unsigned)regs_default(variant_board(v), a));
            vsep = ", ";
        }
        printf("},\n     \"min\": %u, \"max\": %u, \"unit\": ", d->min, regs_max(d));
        if (unit_key(d->unit))
            regdoc_json_str(unit_key(d->unit));
        else
            printf("null");
        printf(", \"signed\": %s,\n     \"doc\": ",
               (d->flags & REG_FLAG_SIGNED) ? "true" : "false");
        regdoc_json_str(d->doc);
        printf("}");
        sep = ",\n";
    }
    printf("\n  ]\n}\n");
    return 0;
}

/* Who acts on a write of register a (write.h's hooks), and the store for EEPROM. */
static void print_owners(uint8_t a)
{
    const char *sep = "";
    for (uint8_t h = 0; h < write_hook_count; h++) {
        const struct write_hook *k = &write_hooks[h];
        if ((k->acts_on >> a) & 1u)
            printf("%s%s at the write", sep, k->owner);
        else if ((k->reads >> a) & 1u)
            printf("%s%s as it works", sep, k->owner);
        else
            continue;
        sep = "; ";
    }
    if (regs_table[a].area == REG_AREA_EE && (regs_table[a].access & REG_ACCESS_W))
        printf("%sstore: kept in flash", sep);
}

static void print_hooks(void)
{
    printf("\n## Who acts on a register\n\n"
           "From the hooks in `src/write.c` (write.h): a module acts on a register when it is "
           "written, or reads it as it works. The store keeps every writable EEPROM register in "
           "flash, whatever changed it ([persistence.md](persistence.md)).\n\n"
           "| module | acts on a write of | reads as it works | what it does |\n"
           "|---|---|---|---|\n");
    for (uint8_t h = 0; h < write_hook_count; h++) {
        const struct write_hook *k = &write_hooks[h];
        printf("| %s | ", k->owner);
        for (int part = 0; part < 2; part++) {
            uint64_t m = part ? k->reads : k->acts_on;
            const char *sep = "";
            for (uint8_t a = 0; a < REGS_SIZE; a++)
                if (((m >> a) & 1u) && regs_table[a].size) {
                    printf("%s%u", sep, a);
                    sep = ", ";
                }
            printf("%s | ", *sep ? "" : "-");
        }
        printf("%s |\n", k->effect);
    }
}

int main(int argc, char **argv)
{
    if (argc == 2 && strcmp(argv[1], "--json") == 0)
        return print_json();
    if (argc == 2 && strcmp(argv[1], "--protocol-json") == 0)
        return regdoc_protocol_json();
    if (argc != 1) {
        fprintf(stderr, "usage: regdoc [--json | --protocol-json]\n");
        return 2;
    }
    printf("# Register reference\n\n"
           "Generated by `build/host/tools/regdoc` from the control table in `src/regs.c`; "
           "do not edit by hand (`make docs` regenerates it, `make test` checks it).\n\n"
           "Variants: B base, F foot, A arm, W wrist, H finger. A register not listed for a "
           "variant reads 0 there and a write to it is an instruction error. Addresses not "
           "listed are reserved (read 0, write refused). Writes must cover whole registers. "
           "Multi-byte values are little-endian.\n\n"
           "| addr | name | size | access | area | variants | default | range | unit | notes | "
           "acted on by |\n"
           "|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (uint8_t a = 0; a < REGS_SIZE; a++) {
        const struct reg_desc *d = &regs_table[a];
        if (!d->size)
            continue;
        if (d->size == 2)
            printf("| %u-%u ", a, a + 1);
        else
            printf("| %u ", a);
        printf("| %s | %u | %s | %s | ", d->name, d->size,
               d->access == REG_ACCESS_R ? "R" : d->access == REG_ACCESS_W ? "W" : "RW",
               d->area == REG_AREA_EE ? "EEPROM" : "RAM");
        for (int v = 0; v < VARIANT_COUNT; v++)
            if (d->variants & REG_V(v))
                putchar(variant_letter[v]);
        printf(" | ");
        print_defaults(a);
        if (d->access & REG_ACCESS_W)
            printf(" | %u-%u", d->min, regs_max(d));
        else
            printf(" | read-only");
        printf(" | %s | %s | ", unit_text(d->unit), d->doc);
        print_owners(a);
        printf(" |\n");
    }
    printf("\n## Baud rates (register 4)\n\n| code | baud |\n|---|---|\n");
    for (uint8_t c = 0; c <= 10; c++) {
        if (c == 0)
            printf("| 0 | variant default (B %u, others %u) |\n",
                   (unsigned)link_baud(&board_base, 0), (unsigned)link_baud(&board_arm, 0));
        else
            printf("| %u | %u |\n", c, (unsigned)link_baud(&board_arm, c));
    }
    print_hooks();
    return 0;
}
