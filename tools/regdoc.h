/* regdoc.h - the parts of the regdoc tool (tools/regdoc.c: the register reference and
 * registers.json; tools/protocol_json.c: protocol.json). */
#ifndef REGDOC_H
#define REGDOC_H

/* A JSON string literal (the tables' texts are ASCII). */
void regdoc_json_str(const char *s);

/* regdoc --protocol-json */
int regdoc_protocol_json(void);

#endif
