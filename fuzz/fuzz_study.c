/* libFuzzer target: the study-file parser (fuzz_study.h). Built and run by `make fuzz`. */
#include "fuzz_study.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return consph_fuzz_study(data, size);
}
