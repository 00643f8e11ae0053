/* libFuzzer target: the inflate entry point of fuzz_targets.h (consph_rd_inflate, the reader's
 * wrapper over the system zlib). Built and run by `make fuzz`. */
#include "fuzz_targets.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return consph_fuzz_inflate(data, size);
}
