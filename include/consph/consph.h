/* consph: consistent, convergent SPH. Include this for the whole public API. */
#ifndef CONSPH_CONSPH_H
#define CONSPH_CONSPH_H

#include "consph/core.h"
#include "consph/kernels.h"
#include "consph/nnps.h"
#include "consph/pass.h"
#include "consph/layout.h"
#include "consph/io.h"
#include "consph/ops.h"
#include "consph/study.h"

#endif
