/* The CUDA timer of stages.h: a pool of events recorded on the default stream (the one every
 * launch of cuda.cu goes to), read when collected. Only bench_gpu's timing uses it. */
#include <cuda_runtime.h>
#include <stdlib.h>

#include "gpu/stages.h"

namespace {

cudaEvent_t *events = NULL;
int used = 0, made = 0, cap = 0;

int ev_mark(void)
{
    if (used == made) {
        if (made == cap) {
            const int c = cap ? 2 * cap : 256;
            cudaEvent_t *e = (cudaEvent_t *)realloc(events, (size_t)c * sizeof *e);
            if (!e) return -1;
            events = e;
            cap = c;
        }
        if (cudaEventCreate(&events[made]) != cudaSuccess) return -1;
        ++made;
    }
    if (cudaEventRecord(events[used], 0) != cudaSuccess) return -1;
    return used++;
}

double ev_ms(int a, int b)
{
    float ms = 0.0f;
    if (cudaEventSynchronize(events[b]) != cudaSuccess ||
        cudaEventElapsedTime(&ms, events[a], events[b]) != cudaSuccess)
        return 0.0;
    return (double)ms;
}

void ev_clear(void)
{
    used = 0;
}

const gpu_timer cuda_timer = {ev_mark, ev_ms, ev_clear};

} // namespace

extern "C" const gpu_timer *gpu_cuda_timer(void)
{
    return &cuda_timer;
}
