/* The floor of a single kernel call on this machine [issue 19, item 2], with harness.h:
 *
 *   floor_bench [REPEATS]
 *
 * Prints one JSON object:
 *   sincos8_ns  sine and cosine of 8 angles (half the Panda joint values, the 8th 0) with glibc's
 *               vector versions, as many calls as the vector width needs (AVX-512: 1 + 1, AVX2: 2 + 2,
 *               SSE2: 4 + 4), per evaluation in the same loop as the kernels; libm's sin and cos where
 *               the build has no libmvec (then "vector": 0)
 *   flop_ns     one scalar double add or multiply at the machine's throughput: 12 independent
 *               multiply-add chains kept in registers
 * run.py's floor of a kernel: sincos8_ns per 8 of its angles + its flops × flop_ns. The libmvec calls
 * are those of gagen's C template (gagen_sincos in kernels.c.j2); compile with gagen's flags.
 */
#include "harness.h" /* first: it sets _POSIX_C_SOURCE */

#include <math.h>
#include <stdio.h>
#include <string.h>

#if defined(GAGEN_HAVE_LIBMVEC) && defined(__AVX512F__)
#define W 8
typedef double vec __attribute__((vector_size(64)));
vec _ZGVeN8v_sin(vec), _ZGVeN8v_cos(vec);
#define VSIN _ZGVeN8v_sin
#define VCOS _ZGVeN8v_cos
#elif defined(GAGEN_HAVE_LIBMVEC) && defined(__AVX2__)
#define W 4
typedef double vec __attribute__((vector_size(32)));
vec _ZGVdN4v_sin(vec), _ZGVdN4v_cos(vec);
#define VSIN _ZGVdN4v_sin
#define VCOS _ZGVdN4v_cos
#elif defined(GAGEN_HAVE_LIBMVEC) && defined(__SSE2__)
#define W 2
typedef double vec __attribute__((vector_size(16)));
vec _ZGVbN2v_sin(vec), _ZGVbN2v_cos(vec);
#define VSIN _ZGVbN2v_sin
#define VCOS _ZGVbN2v_cos
#endif

static void sincos8(const double *x, double *s, double *c) {
#ifdef W
    for (int i = 0; i < 8; i += W) {
        vec v, r;
        memcpy(&v, x + i, sizeof v);
        r = VSIN(v);
        memcpy(s + i, &r, sizeof r);
        r = VCOS(v);
        memcpy(c + i, &r, sizeof r);
    }
#else
    for (int i = 0; i < 8; ++i) {
        s[i] = sin(x[i]);
        c[i] = cos(x[i]);
    }
#endif
}

/* 12 independent multiply-add chains (latency 6-8 cycles each: enough in flight for 2-4 flops a
 * cycle). On x86-64 the loop is written in assembly: compiled from C, GCC moved the chains through
 * integer registers every iteration and measured its own spills (0.14-0.34 ns a flop, against 0.08). */
#if defined(__x86_64__) && defined(__AVX__)
#define MUL_ADD(k) "vmulsd %[m], %[v" #k "], %[v" #k "]\n\tvaddsd %[a], %[v" #k "], %[v" #k "]\n\t"
#elif defined(__x86_64__)
#define MUL_ADD(k) "mulsd %[m], %[v" #k "]\n\taddsd %[a], %[v" #k "]\n\t"
#endif

__attribute__((noinline)) static double flop_ns(void) {
    double v0 = 1.0, v1 = 1.1, v2 = 1.2, v3 = 1.3, v4 = 1.4, v5 = 1.5, v6 = 1.6, v7 = 1.7, v8 = 1.8,
           v9 = 1.9, v10 = 2.0, v11 = 2.1, m = 0.999999999, a = 1e-12, best = 1e30;
    const long n = 2000000;
    __asm__ __volatile__("" : "+x"(m), "+x"(a));
    for (int r = 0; r < 21; ++r) {
        const uint64_t t0 = bench_now_ns();
#ifdef MUL_ADD
        long i = n; /* the whole loop in assembly: the chains stay in their registers */
        __asm__ __volatile__("1:\n\t"
                             MUL_ADD(0) MUL_ADD(1) MUL_ADD(2) MUL_ADD(3) MUL_ADD(4) MUL_ADD(5)
                             MUL_ADD(6) MUL_ADD(7) MUL_ADD(8) MUL_ADD(9) MUL_ADD(10) MUL_ADD(11)
                             "dec %[i]\n\tjnz 1b"
                             : [v0] "+x"(v0), [v1] "+x"(v1), [v2] "+x"(v2), [v3] "+x"(v3), [v4] "+x"(v4),
                               [v5] "+x"(v5), [v6] "+x"(v6), [v7] "+x"(v7), [v8] "+x"(v8), [v9] "+x"(v9),
                               [v10] "+x"(v10), [v11] "+x"(v11), [i] "+r"(i)
                             : [m] "x"(m), [a] "x"(a)
                             : "cc");
#else
        for (long i = 0; i < n; ++i) {
            v0 = v0 * m + a; v1 = v1 * m + a; v2 = v2 * m + a; v3 = v3 * m + a; v4 = v4 * m + a;
            v5 = v5 * m + a; v6 = v6 * m + a; v7 = v7 * m + a; v8 = v8 * m + a; v9 = v9 * m + a;
            v10 = v10 * m + a; v11 = v11 * m + a;
            __asm__ __volatile__("" : "+x"(v0), "+x"(v1), "+x"(v2), "+x"(v3), "+x"(v4), "+x"(v5));
            __asm__ __volatile__("" : "+x"(v6), "+x"(v7), "+x"(v8), "+x"(v9), "+x"(v10), "+x"(v11));
        }
#endif
        const double ns = (double)(bench_now_ns() - t0) / (n * 24.0);
        if (ns < best) best = ns; /* the throughput: the fastest of the repeats */
    }
    if (v0 + v1 + v2 + v3 + v4 + v5 + v6 + v7 + v8 + v9 + v10 + v11 == 0.0) printf("#");
    return best;
}

int main(int argc, char **argv) {
    const int repeats = bench_repeats(argc, argv);
    double *qs = bench_configs(BENCH_N, 7, bench_panda_lower, bench_panda_upper, BENCH_SEED);
    double x[8] = {0}, s[8], c[8], checksum = 0, trig_ns;
    BENCH_PER_CALL(trig_ns, repeats, BENCH_N, qs, 7, q, {
        for (int j = 0; j < 7; ++j) x[j] = 0.5 * q[j];
        sincos8(x, s, c);
        bench_clobber(s);
        bench_clobber(c);
        checksum += s[6] + c[6];
    });
    const double flop = flop_ns();
    bench_json_begin();
    bench_json_num("sincos8_ns", trig_ns);
    bench_json_num("flop_ns", flop);
#ifdef W
    bench_json_num("vector", W);
#else
    bench_json_num("vector", 0);
#endif
    bench_json_end(checksum);
    free(qs);
    return 0;
}
