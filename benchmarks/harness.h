/* Shared timing harness of the C benchmarks (C99 and C++; header only).
 *
 * Every timing program draws the same configurations (bench_configs: a fixed xorshift stream,
 * uniform within the Panda joint limits), times a loop over all of them, repeats the loop and
 * reports the median time per evaluation. A checksum of one output per call is accumulated and
 * printed, and bench_clobber() is an optimisation barrier in the manner of
 * benchmark::DoNotOptimize, so the compiler can neither drop nor hoist the work.
 *
 *   double *qs = bench_configs(BENCH_N, 7, bench_panda_lower, bench_panda_upper, BENCH_SEED);
 *   double ns, checksum = 0;
 *   BENCH_PER_CALL(ns, repeats, BENCH_N, qs, 7, q, {
 *       my_fk(q, M, P);
 *       bench_clobber(M);
 *       checksum += M[0];
 *   });
 *
 * Output is one JSON object per program (bench_json_*), read by run.py.
 */
#ifndef GAGEN_BENCH_HARNESS_H
#define GAGEN_BENCH_HARNESS_H

#if !defined(_POSIX_C_SOURCE) && !defined(__cplusplus)
#define _POSIX_C_SOURCE 200112L /* clock_gettime under -std=c99; include this header first */
#endif

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define BENCH_N 1000      /* configurations per timed loop */
#define BENCH_REPEATS 51  /* timed loops; the median is reported (>= 21) */
#define BENCH_SEED 20240611u

/* Panda joint limits, as in robots/panda/panda.urdf */
static const double bench_panda_lower[7] = {-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973};
static const double bench_panda_upper[7] = {2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973};

static inline uint64_t bench_now_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

/* An optimisation barrier: the compiler must assume *p is read and any memory is written. */
static inline void bench_clobber(const void *p) {
#if defined(__GNUC__) || defined(__clang__)
    __asm__ __volatile__("" : : "r"(p) : "memory");
#else
    (void)p;
#endif
}

static inline uint64_t bench_xorshift(uint64_t *s) {
    uint64_t x = *s;
    x ^= x << 13;
    x ^= x >> 7;
    x ^= x << 17;
    return *s = x;
}

/* n configurations of dof values, column-major (configuration s at qs + dof*s), uniform in [lo, hi]. */
static inline double *bench_configs(long n, int dof, const double *lo, const double *hi, uint64_t seed) {
    double *qs = (double *)malloc(sizeof(double) * (size_t)(n * dof));
    uint64_t s = seed * 0x9E3779B97F4A7C15ull + 1;
    for (long i = 0; i < n; ++i)
        for (int j = 0; j < dof; ++j) {
            double u = (double)(bench_xorshift(&s) >> 11) * (1.0 / 9007199254740992.0);
            volatile double step = u * (hi[j] - lo[j]); /* rounded: no FMA, same doubles as Python */
            qs[i * dof + j] = lo[j] + step;
        }
    return qs;
}

static inline int bench_cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static inline double bench_median(double *v, int n) {
    qsort(v, (size_t)n, sizeof(double), bench_cmp_double);
    return (n % 2) ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* The doubles of a file written by a Python driver (numpy's tobytes): a malloc'd array and its length,
 * or NULL when the file cannot be read. */
static inline double *bench_read_doubles(const char *path, long *count) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long bytes = ftell(f);
    fseek(f, 0, SEEK_SET);
    double *data = (double *)malloc((size_t)(bytes > 0 ? bytes : 1));
    *count = bytes / (long)sizeof(double);
    if (fread(data, sizeof(double), (size_t)*count, f) != (size_t)*count) {
        fclose(f);
        free(data);
        return NULL;
    }
    fclose(f);
    return data;
}

/* repeats from argv[1] (default BENCH_REPEATS, at least 21) */
static inline int bench_repeats(int argc, char **argv) {
    int r = argc > 1 ? atoi(argv[1]) : BENCH_REPEATS;
    return r < 21 ? 21 : r;
}

/* Median over `repeats` timed loops (after one untimed warm-up loop) of the time per configuration
 * of BODY, run once per configuration with `qvar` pointing at it. */
#define BENCH_PER_CALL(result_ns, repeats, n, qs, dof, qvar, BODY)                                   \
    do {                                                                                          \
        double *bench_t_ = (double *)malloc(sizeof(double) * (size_t)(repeats));                  \
        for (int bench_r_ = -1; bench_r_ < (repeats); ++bench_r_) {                               \
            uint64_t bench_t0_ = bench_now_ns();                                                  \
            for (long bench_i_ = 0; bench_i_ < (n); ++bench_i_) {                                 \
                const double *qvar = (qs) + (long)(dof) * bench_i_;                               \
                BODY                                                                              \
            }                                                                                     \
            uint64_t bench_t1_ = bench_now_ns();                                                  \
            if (bench_r_ >= 0) bench_t_[bench_r_] = (double)(bench_t1_ - bench_t0_) / (double)(n); \
        }                                                                                         \
        (result_ns) = bench_median(bench_t_, (repeats));                                          \
        free(bench_t_);                                                                           \
    } while (0)

/* The same for a batched kernel: BODY processes all n configurations at once. */
#define BENCH_BATCH(result_ns, repeats, n, BODY)                                                  \
    do {                                                                                          \
        double *bench_t_ = (double *)malloc(sizeof(double) * (size_t)(repeats));                  \
        for (int bench_r_ = -1; bench_r_ < (repeats); ++bench_r_) {                               \
            uint64_t bench_t0_ = bench_now_ns();                                                  \
            BODY                                                                                  \
            uint64_t bench_t1_ = bench_now_ns();                                                  \
            if (bench_r_ >= 0) bench_t_[bench_r_] = (double)(bench_t1_ - bench_t0_) / (double)(n); \
        }                                                                                         \
        (result_ns) = bench_median(bench_t_, (repeats));                                          \
        free(bench_t_);                                                                           \
    } while (0)

/* JSON: bench_json_begin(); bench_json_num("fk_ns", x); ...; bench_json_end(checksum); */
static int bench_json_first_ = 1;
static inline void bench_json_begin(void) { printf("{"); bench_json_first_ = 1; }
static inline void bench_json_num(const char *key, double v) {
    printf("%s\"%s\": %.6g", bench_json_first_ ? "" : ", ", key, v);
    bench_json_first_ = 0;
}
static inline void bench_json_end(double checksum) {
    bench_json_num("checksum", checksum);
    bench_json_num("n_configs", BENCH_N);
    printf("}\n");
}

#endif
