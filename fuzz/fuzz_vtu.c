/* libFuzzer target: the vtu entry point of fuzz_targets.h. Built and run by `make fuzz`. */
#include "fuzz_targets.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return consph_fuzz_vtu(data, size);
}
