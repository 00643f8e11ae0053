/* The run parameters in a checkpoint's metadata (src/solver/restore.c), from the table of
 * src/solver/params.def: one "name=value" line each, doubles in C99 hexadecimal (%a) so they
 * read back bit for bit, enums, kernels and layouts as their integer values. */
#ifndef CONSPH_SOLVER_PARAMS_H
#define CONSPH_SOLVER_PARAMS_H

#include <stddef.h>

#include "consph/solver.h"

/* Appends the lines of every parameter to buf (holding `used` bytes of text already); the new
 * length, or -1 when buf (size) is too small. */
int run_params_meta_write(const consph_run_params *prm, char *buf, size_t size, size_t used);
/* The value `v` of the key `k` into prm: 1 when set, 0 when not a value of its type (integers
 * within the range of their member; bounds are consph_run_params_check's), -1 when `k` is no
 * parameter. */
int run_params_meta_read(consph_run_params *prm, const char *k, const char *v);
/* The parameter a message of consph_run_params_check is about: its name or option begins the
 * message ("hdx = 7 ...", "--nx must ..."); NULL when none does. */
const consph_run_param *run_param_of_message(const char *msg);

#endif
