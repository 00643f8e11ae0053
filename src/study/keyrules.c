/* The key table of study files (docs/studies.md): every key, the figure kinds that read it and
 * where it may stand, so that a key no figure reads is refused at its line instead of being
 * ignored without a word. */
#include <stdio.h>
#include <string.h>

#include "consph/solver.h"
#include "study/keyrules.h"

/* Every key a study file may set, the figure kinds that read it and where (docs/studies.md):
 * a key no figure reads would be ignored without a word. */
static const key_rule key_rules[] = {{"study", K_ALL, AT_STUDY},
                                     {"title", K_ALL, AT_HEAD},
                                     {"paper", K_ALL, AT_HEAD},
                                     {"note", K_ALL, AT_HEAD},
                                     {"kind", K_ALL, AT_HEAD},
                                     {"op", K_APPROX, AT_ANY},
                                     {"form", K_APPROX, AT_ANY},
                                     {"corr", K_APPROX, AT_ANY},
                                     {"field", K_APPROX, AT_ANY},
                                     {"sigma", K_APPROX, AT_ANY},
                                     {"mask", K_APPROX, AT_ANY},
                                     {"bound", K_APPROX, AT_ANY},
                                     {"sweep", K_APPROX, AT_ANY},
                                     {"hdx.values", K_APPROX, AT_ANY},
                                     {"quick.hdx.values", K_APPROX, AT_ANY},
                                     {"norm", K_APPROX, AT_HEAD},
                                     {"x", K_APPROX | K_RUN, AT_HEAD},
                                     {"kernel", K_LAYOUT, AT_ANY},
                                     {"hdx", K_LAYOUT | K_HEAT, AT_ANY},
                                     {"h_policy", K_LAYOUT, AT_ANY},
                                     {"match_support", K_LAYOUT, AT_ANY},
                                     {"beta", K_LAYOUT, AT_ANY},
                                     {"layout", K_LAYOUT, AT_ANY},
                                     {"dim", K_LAYOUT | K_APPC, AT_ANY},
                                     {"eps", K_LAYOUT | K_HEAT, AT_ANY},
                                     {"seed", K_LAYOUT | K_HEAT, AT_ANY},
                                     {"periodic", K_LAYOUT, AT_ANY},
                                     {"volume", K_LAYOUT, AT_ANY},
                                     {"pack_tol", K_LAYOUT, AT_ANY},
                                     {"pack_iter", K_LAYOUT, AT_ANY},
                                     {"pack_walls", K_LAYOUT, AT_ANY},
                                     {"nx", K_ALL, AT_ANY},
                                     {"quick.nx", K_ALL, AT_ANY},
                                     {"hdelta.values", K_APPC, AT_ANY},
                                     {"bins", K_M0, AT_ANY},
                                     {"range", K_M0, AT_ANY},
                                     {"measure", K_CAUCHY, AT_ANY},
                                     {"ot_method", K_CAUCHY, AT_ANY},
                                     {"ot_p", K_CAUCHY, AT_ANY},
                                     {"directions", K_CAUCHY, AT_ANY},
                                     {"grid", K_CAUCHY, AT_ANY},
                                     {"tf", K_HEAT, AT_ANY},
                                     {"dt_rule", K_RUN, AT_ANY},
                                     {"l1", K_RUN, AT_ANY},
                                     {"tr_ref", K_RUN, AT_HEAD},
                                     {"device", K_RUN, AT_STUDY},
                                     {"y", K_RUN, AT_HEAD},
                                     {"laplacian", K_HEAT, AT_ANY},
                                     {"walls", K_HEAT, AT_ANY},
                                     {"report", K_HEAT, AT_HEAD},
                                     {"paper.", K_ALL, AT_ANY},
                                     {"series.", K_ALL, AT_FIGURE},
                                     {NULL, 0, 0}};

/* The run parameters' study keys (consph_run_param_at) are keys of run figures, and `quick.KEY`
 * of those a quick run replaces. */
static int run_param_key(const char *key)
{
    for (int k = 0; k < consph_run_param_count(); ++k) {
        const consph_run_param *d = consph_run_param_at(k);
        if (!d->study_key) continue;
        if (strcmp(key, d->study_key) == 0) return 1;
        if ((d->flags & CONSPH_PFLAG_QUICK) && strncmp(key, "quick.", 6) == 0 &&
            strcmp(key + 6, d->study_key) == 0)
            return 1;
    }
    return 0;
}

/* The rule of `key` into *out: key_rules' row, with run figures added for a run parameter; 0
 * when the key is unknown. */
int study_key_rule_of(const char *key, key_rule *out)
{
    const key_rule *found = NULL;
    for (const key_rule *k = key_rules; k->name && !found; ++k) {
        size_t n = strlen(k->name);
        if (k->name[n - 1] == '.') {
            if (strncmp(key, k->name, n) == 0 && key[n]) found = k;
        } else if (strcmp(key, k->name) == 0) {
            found = k;
        }
    }
    const int run = run_param_key(key);
    if (!found && !run) return 0;
    *out = found ? *found : (key_rule){key, 0, AT_ANY};
    if (run) out->kinds |= K_RUN;
    return 1;
}

/* The kinds of a rule as text ("approx, m0"). */
static const char *kinds_text(int kinds, char *buf, size_t size)
{
    buf[0] = '\0';
    for (int k = 0; study_kind_names[k]; ++k)
        if (kinds & (1 << k)) {
            if (buf[0]) strncat(buf, ", ", size - strlen(buf) - 1);
            strncat(buf, study_kind_names[k], size - strlen(buf) - 1);
        }
    return buf;
}

/* The kind bit of a figure (its `kind`, else the study's, else approx); 0 when unknown (the
 * engine names the allowed values). */
static int figure_kind_bit(const consph_study *s, const study_figure *f)
{
    const char *kind = study_get(s, f, NULL, "kind");
    if (!kind) return K_APPROX;
    for (int k = 0; study_kind_names[k]; ++k)
        if (strcmp(kind, study_kind_names[k]) == 0) return 1 << k;
    return 0;
}

/* A key set where no figure reads it: on a figure (or series) of a kind that does not, or on
 * the study when no figure is of a kind that does. */
static int key_applies(const consph_study *s, const study_kv *kv, int kinds, const char *where)
{
    const char *key = strncmp(kv->key, "series.", 7) == 0 ? kv->key + 7 : kv->key;
    key_rule rule_row;
    const key_rule *rule = study_key_rule_of(key, &rule_row) ? &rule_row : NULL;
    if (!rule || (rule->kinds & kinds)) return CONSPH_OK;
    char buf[64], have[64];
    return consph_fail(CONSPH_EFORMAT,
                       "%s:%d: key '%s' does not apply to %s (kind %s); it applies to kind %s",
                       s->path, kv->line, kv->key, where, kinds_text(kinds, have, sizeof have),
                       kinds_text(rule->kinds, buf, sizeof buf));
}

int study_check_kinds(const consph_study *s)
{
    int all = 0, rc;
    char where[160];
    for (int k = 0; k < s->nfigs; ++k) {
        const study_figure *f = &s->figs[k];
        int kb = figure_kind_bit(s, f);
        if (!kb) return CONSPH_OK;
        all |= kb;
        snprintf(where, sizeof where, "figure '%s'", f->id);
        for (int j = 0; j < f->keys.n; ++j)
            if ((rc = key_applies(s, &f->keys.items[j], kb, where))) return rc;
        for (int r = 0; r < f->nseries; ++r)
            for (int j = 0; j < f->series[r].keys.n; ++j)
                if ((rc = key_applies(s, &f->series[r].keys.items[j], kb, where))) return rc;
        /* These kinds measure their first series only. */
        if ((kb & (K_M0 | K_APPC)) && f->nseries > 1)
            return consph_fail(CONSPH_EFORMAT,
                               "%s:%d: figure '%s' (kind %s) has one series; a second is not "
                               "measured",
                               s->path, f->series[1].line, f->id, kinds_text(kb, where, 16));
    }
    for (int j = 0; j < s->keys.n; ++j)
        if ((rc = key_applies(s, &s->keys.items[j], all, "any figure of this study"))) return rc;
    return CONSPH_OK;
}
