/* FMU states as bytes, packed and unpacked by the loader itself (state_bytes.c), to the layout the slave's
 * (de)serializers give (src/stickslip/core/state_bytes.py, BlockStateFormat), without a call into Python for the
 * fields of each state.
 *
 * The slave hands the loader its format's plan once (its attribute state_plan, BlockStateFormat.loader_plan: the
 * header, the shape of a state's tuples, and each field's place in them and kind). The parts that states share (the
 * parameters, the segment, the model-exchange block) the loader takes from the last state the slave's Python packed
 * or unpacked (the template): a state whose parts are the template's objects is packed here, each field of its own
 * written from its place; bytes whose parts are the template's bytes are unpacked here, each field of their own
 * checked as the slave checks it (a finite real, a count >= 0, a flag 0 or 1, ...), the values checked together by
 * the slave's compiled check (checked_like). Anything else (another part, a field out of its kind, a refused
 * state, bytes of another FMU) is left to the slave's Python, which gives the same bytes and states, or the reason
 * for a refusal; its result then becomes the template. Every function is called under the GIL.
 */
#ifndef SBF_STATE_BYTES_H
#define SBF_STATE_BYTES_H
#include <stddef.h>

typedef struct sbf_state_plan sbf_state_plan;

/* Resolve the CPython functions the plans use from `libpython`; 0 if one is missing (then no plan is made). */
int sbf_state_bytes_resolve(void *libpython);

/* The plan of the slave `slave` (its state_plan), or NULL if it offers none or it is malformed (no Python exception
 * is left pending). */
sbf_state_plan *sbf_plan_new(void *slave);
void sbf_plan_free(sbf_state_plan *plan);

/* The bytes of `state` packed here: their size (the bytes in *bytes, valid until the plan's next call), or -1 if
 * its parts are not the template's or a field is not of its kind (ask the slave, then sbf_plan_packed). */
long sbf_plan_pack(sbf_state_plan *plan, void *state, const unsigned char **bytes);
/* The slave packed `state` as bytes[0..size): its parts and their bytes become the template for packing. */
void sbf_plan_packed(sbf_state_plan *plan, void *state, const unsigned char *bytes, size_t size);

/* The state of bytes[0..size) unpacked here (a new reference), or NULL if they are not the template's in their
 * parts or a field or the values together are refused (no Python exception is left pending: ask the slave, then
 * sbf_plan_unpacked). */
void *sbf_plan_unpack(sbf_state_plan *plan, const unsigned char *bytes, size_t size);
/* The slave unpacked bytes[0..size) as `state`: they and its objects become the template for unpacking. */
void sbf_plan_unpacked(sbf_state_plan *plan, void *state, const unsigned char *bytes, size_t size);

#endif
