/* The fuzz entry point of the study-file parser, shared by the libFuzzer target fuzz_study.c
 * (built by `make fuzz FUZZ_TARGETS=study`) and by tests/test_studyfile.c, which replays the
 * seed corpus fuzz/corpus/study/ and every crash kept in fuzz/regressions/study/.
 *
 * Whatever the bytes, a parse either fails with a message and no study, or yields a study whose
 * names are plain (they become file names and gnuplot strings); validating it for the quick and
 * the full resolutions then succeeds or fails with a message. Anything else aborts. */
#ifndef CONSPH_FUZZ_STUDY_H
#define CONSPH_FUZZ_STUDY_H

#include <string.h>

#include "consph/study.h"
#include "fuzz_targets.h"
#include "study/study_internal.h"

static inline int consph_fuzz_study(const uint8_t *data, size_t size)
{
    consph_study *s = (consph_study *)1;
    int rc = study_parse("fuzz.study", (const char *)data, size, &s);
    if (rc != CONSPH_OK) {
        fuzz_require(s == NULL, "a failed parse returns no study");
        fuzz_require(consph_last_error()[0] != '\0', "a failed parse leaves a message");
        return 0;
    }
    fuzz_require(s && s->nfigs > 0, "a study has figures");
    fuzz_require(study_plain_name(consph_study_name(s), 0), "a plain study name");
    for (int k = 0; k < s->nfigs; ++k) {
        const study_figure *f = &s->figs[k];
        fuzz_require(study_plain_name(f->id, 0), "plain figure ids");
        fuzz_require(f->nseries > 0, "every figure has a series");
        for (int j = 0; j < k; ++j)
            fuzz_require(strcmp(s->figs[j].id, f->id) != 0, "distinct figure ids");
        for (int r = 0; r < f->nseries; ++r)
            fuzz_require(f->series[r].label && f->series[r].label[0], "series labels");
    }
    for (int quick = 0; quick < 2; ++quick)
        if (consph_study_validate(s, quick) != CONSPH_OK)
            fuzz_require(consph_last_error()[0] != '\0', "a failed validation has a message");
    consph_study_free(s);
    return 0;
}

#endif
