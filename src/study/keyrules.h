/* The keys a study file may set: which figure kinds read each and where it may stand
 * (keyrules.c); the run parameters' keys come from the parameter table. */
#ifndef CONSPH_STUDY_KEYRULES_H
#define CONSPH_STUDY_KEYRULES_H

#include "study/kinds/kinds.h"
#include "study/study_internal.h"

/* The figure kinds (`kind`), as bits of key_rule.kinds: bit k is study_kinds[k], the
 * registry's (kinds/kinds.h). */
#define STUDY_KIND_BIT(name) K_BIT_##name,
enum { STUDY_KINDS(STUDY_KIND_BIT) K_COUNT };
#undef STUDY_KIND_BIT
enum {
    K_APPROX = 1 << K_BIT_approx,
    K_M0 = 1 << K_BIT_m0,
    K_APPC = 1 << K_BIT_appc,
    K_CAUCHY = 1 << K_BIT_cauchy,
    K_RUN = 1 << K_BIT_run,
    K_HEAT = 1 << K_BIT_heat,
    K_ALL = (1 << K_COUNT) - 1,
    K_LAYOUT = K_APPROX | K_M0 | K_CAUCHY /* the kinds measuring generated layouts */
};

/* Where a key may be set: before the first section, on a [figure], in a [series]. Keys read
 * once per figure (its title, axes, report) mean nothing in a series. */
enum { AT_STUDY = 1, AT_FIGURE = 2, AT_SERIES = 4, AT_HEAD = 3, AT_ANY = 7 };

typedef struct key_rule {
    const char *name; /* ending in '.': a prefix */
    int kinds, at;
} key_rule;

/* The rule of `key` into *out: the key table's row, with run figures added for a run
 * parameter; 0 when the key is unknown. */
int study_key_rule_of(const char *key, key_rule *out);
/* CONSPH_EFORMAT at file:line for a key set where no figure reads it, or a second series of a
 * kind that measures its first only. */
int study_check_kinds(const consph_study *s);

#endif
