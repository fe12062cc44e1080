/* protocol_json.c - `regdoc --protocol-json`: the instruction table (src/dispatch.c), CUSTOM's
 * sub-commands and the ERR bits (include/proto.h) as JSON for the host SDK
 * (tools/python/servobus/protocol.json; CTest docs.protocol_json fails when the copy
 * drifts). The SDK's instruction codes, its ERR-bit names and the set of instructions that
 * spend flash commits (its budget model) come from here, not from a hand copy. */
#include <stdio.h>

#include "dispatch.h"
#include "proto.h"
#include "regdoc.h"

static const struct {
    uint8_t bit;
    const char *name, *words;
} err_bits[] = {
    {ERR_OVER_TEMPERATURE, "over_temperature", "over-temperature"},
    {ERR_OVER_CURRENT, "over_current", "over-current"},
    {ERR_OVER_VOLTAGE, "over_voltage", "over-voltage"},
    {ERR_UNDER_VOLTAGE, "under_voltage", "under-voltage"},
    {ERR_CHECKSUM, "checksum", "checksum error"},
    {ERR_INSTRUCTION, "instruction", "instruction error"},
    {ERR_STALL, "stall", "stall"},
};

static const struct {
    uint8_t flag;
    const char *name;
} flags[] = {
    {INS_ANSWER_LEVEL1, "answer_level1"}, {INS_ANSWER_ALWAYS, "answer_always"},
    {INS_IN_UPDATE, "in_update"},         {INS_MOVES, "moves"},
    {INS_COMMITS, "commits"},             {INS_BROADCAST_ONLY, "broadcast_only"},
    {INS_OWN_ANSWER, "own_answer"},
};

static void print_entries(const struct instruction *t, uint8_t count, const char *code_key)
{
    for (uint8_t i = 0; i < count; i++) {
        printf("    {\"%s\": %u, \"name\": ", code_key, t[i].code);
        regdoc_json_str(t[i].name);
        printf(", \"params_min\": %u, \"params_max\": %u, \"flags\": [", t[i].min_n, t[i].max_n);
        const char *sep = "";
        for (size_t f = 0; f < sizeof flags / sizeof flags[0]; f++)
            if (t[i].flags & flags[f].flag) {
                printf("%s\"%s\"", sep, flags[f].name);
                sep = ", ";
            }
        printf("]}%s\n", i + 1u < count ? "," : "");
    }
}

int regdoc_protocol_json(void)
{
    printf("{\n  \"generator\": \"regdoc --protocol-json (from src/dispatch.c and "
           "include/proto.h; do not edit)\",\n  \"header\": [%u, %u],\n  \"broadcast_id\": %u,\n"
           "  \"instructions\": [\n",
           PROTO_HEADER0, PROTO_HEADER1, PROTO_ID_BROADCAST);
    print_entries(dispatch_instructions, dispatch_instruction_count, "code");
    printf("  ],\n  \"custom_subs\": [\n");
    print_entries(dispatch_custom, dispatch_custom_count, "sub");
    printf("  ],\n  \"update_subs\": {\"enter\": %u, \"block\": %u},\n  \"err_bits\": [\n",
           PROTO_UPDATE_SUB_ENTER, PROTO_UPDATE_SUB_BLOCK);
    for (size_t i = 0; i < sizeof err_bits / sizeof err_bits[0]; i++)
        printf("    {\"bit\": %u, \"name\": \"%s\", \"words\": \"%s\"}%s\n", err_bits[i].bit,
               err_bits[i].name, err_bits[i].words,
               i + 1u < sizeof err_bits / sizeof err_bits[0] ? "," : "");
    printf("  ]\n}\n");
    return 0;
}
