/* Pass 1's group visits invert four particles' Bonet moments at once (kv_invert in
 * src/schemes/negi/kit.c, one lane per particle). Each lane must run ops_invert_n's arithmetic
 * (src/ops/small.h) in its order: the same success or failure, and where it succeeds the same
 * inverse bit for bit. Checked on 2 × 2 and 3 × 3 matrices that take every branch of
 * ops_invert_n: row swaps for a larger pivot below, zero factors (rows skipped), a zero row or
 * column, a singular matrix, a condition above the limit, NaN and infinite entries, mixed
 * scales (equilibration), and random ones, in every lane position. */
#include <float.h>
#include <stdint.h>

#include "check.h"
#include "ops/small.h"

/* src/schemes/negi/kit.c */
int kit_invert_lanes(int n, const double *a, double cond_max, double *ainv, int ok[4]);

static uint64_t rng = 0x9e3779b97f4a7c15ull;

static double uniform(double lo, double hi)
{
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return lo + (hi - lo) * (double)(rng >> 11) * 0x1.0p-53;
}

/* Matrix kind k (0..KINDS-1) of size n into a */
#define KINDS 14
static void make(int n, int k, double *a)
{
    for (int e = 0; e < n * n; ++e) a[e] = uniform(-1.0, 1.0);
    switch (k) {
    case 0: /* random */
        break;
    case 1: /* the pivot below: |a10| > |a00| */
        a[0] = 1e-3;
        a[n] = 2.0;
        break;
    case 2: /* diagonal: every factor zero */
        for (int r = 0; r < n; ++r)
            for (int c = 0; c < n; ++c)
                if (r != c) a[r * n + c] = 0.0;
        break;
    case 3: /* a zero row */
        for (int c = 0; c < n; ++c) a[n + c] = 0.0;
        break;
    case 4: /* a zero column */
        for (int r = 0; r < n; ++r) a[r * n + n - 1] = 0.0;
        break;
    case 5: /* singular: the last row a copy of the first */
        for (int c = 0; c < n; ++c) a[(n - 1) * n + c] = a[c];
        break;
    case 6: /* nearly singular: condition far above 1e12 */
        for (int c = 0; c < n; ++c) a[(n - 1) * n + c] = a[c] * (1.0 + 1e-15 * (c + 1));
        break;
    case 7: /* a NaN */
        a[n * n - 1] = NAN;
        break;
    case 8: /* an infinity */
        a[1] = -INFINITY;
        break;
    case 9: /* mixed scales, as a moment of ∇W's units */
        for (int r = 0; r < n; ++r)
            for (int c = 0; c < n; ++c) a[r * n + c] *= pow(10.0, 3 * r - 2 * c);
        break;
    case 10: /* symmetric negative definite, as -Σ ω W'/r x x (the kit's moment) */
        for (int r = 0; r < n; ++r)
            for (int c = 0; c <= r; ++c) a[r * n + c] = a[c * n + r];
        for (int r = 0; r < n; ++r) a[r * n + r] = -(double)n - fabs(a[r * n + r]);
        break;
    case 11: /* a zero in the first pivot */
        a[0] = 0.0;
        break;
    case 12: /* negative zeros and a subnormal */
        a[1] = -0.0;
        a[n] = 0x1.0p-1060;
        break;
    case 13: /* all equal magnitudes (ties in the pivot search) */
        for (int e = 0; e < n * n; ++e) a[e] = e % 3 ? 1.0 : -1.0;
        break;
    }
}

static int same_bits(double x, double y)
{
    return !memcmp(&x, &y, sizeof x);
}

int main(void)
{
    double a[4 * 9] = {0.0}, inv[4 * 9];
    int ok[4];
    if (!kit_invert_lanes(2, a, 1e12, inv, ok)) {
        printf("test_kit_invert: no vector lanes in this build (the group visits do not run)\n");
        return 77;
    }
    const double conds[3] = {1e12, 1e3, INFINITY};
    int failed_lanes = 0, good_lanes = 0;
    for (int n = 2; n <= 3; ++n)
        for (int trial = 0; trial < 400; ++trial)
            for (int ci = 0; ci < 3; ++ci) {
                const double cond_max = conds[ci];
                /* lane l of trial t holds kind (t + 5 l) % KINDS: every kind in every lane,
                 * beside every other */
                int kind[4];
                for (int l = 0; l < 4; ++l) {
                    kind[l] = (trial + 5 * l) % KINDS;
                    make(n, kind[l], a + l * n * n);
                }
                CHECK(kit_invert_lanes(n, a, cond_max, inv, ok), "n %d", n);
                for (int l = 0; l < 4; ++l) {
                    double ref[9];
                    double cond = 0.0;
                    const int want = ops_invert_n(n, a + l * n * n, ref, cond_max, &cond);
                    CHECK(ok[l] == want, "n %d, kind %d, lane %d, cond_max %g: %d, not %d", n,
                          kind[l], l, cond_max, ok[l], want);
                    if (!want || ok[l] != want) {
                        ++failed_lanes;
                        continue;
                    }
                    ++good_lanes;
                    for (int e = 0; e < n * n; ++e)
                        CHECK(same_bits(inv[l * n * n + e], ref[e]),
                              "n %d, kind %d, lane %d, entry %d: %.17g, not %.17g", n, kind[l], l,
                              e, inv[l * n * n + e], ref[e]);
                }
            }
    /* the cases must take both ways, or the test shows nothing */
    CHECK(failed_lanes > 1000 && good_lanes > 1000, "%d lanes failed, %d succeeded", failed_lanes,
          good_lanes);
    return check_summary("test_kit_invert");
}
