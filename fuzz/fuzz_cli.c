/* libFuzzer target: the CLI option parsers through consph_fuzz_cli (fuzz_cli.h). Built and run
 * by `make fuzz`. */
#include "fuzz_cli.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return consph_fuzz_cli(data, size);
}
