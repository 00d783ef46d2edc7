/* Times gagen's generated C for the bundled single-Panda system (generated/panda_point/) with harness.h.
 *
 *   gagen_fk_bench [REPEATS] [BIG_N]
 *
 * Prints one JSON object: fk_ns, fk_jacobian_ns (one call per configuration), fk_batch_ns,
 * fk_jacobian_batch_ns (one batched call over all BENCH_N configurations, divided by BENCH_N),
 * fk_jacobian_batch_big_ns (the same over BIG_N, default 100 000, configurations: median of 5 batches),
 * fk_jacobian_batch_columns_ns and fk_jacobian_batch_columns_big_ns (the same two batches in the column
 * layout, panda_point_arm0_fk_jacobian_batch_columns, on 64-byte-aligned arrays),
 * and the first configuration's P (e0, e1, e2, e3, e∞) and J_S (6×7, column-major,
 * [e12 e13 e23 e1∞ e2∞ e3∞]) for run.py's cross-check against Pinocchio.
 *
 * run.py links it twice: against the kernels compiled with gagen's own flags and with -O3.
 *
 * The API (generated/panda_point/panda_point.h), all arrays column-major, all outputs required:
 *   panda_point_arm0_fk(q[7], M[8], P[5])
 *   panda_point_arm0_fk_jacobian(q[7], M[8], P[5], J_S[42])
 *   panda_point_arm0_fk_batch(n, q[7n], M[8n], P[5n]) and panda_point_arm0_fk_jacobian_batch(n, ..., J_S[42n])
 */
#include "harness.h" /* first: it sets _POSIX_C_SOURCE */

#include <stdio.h>

#include "panda_point.h"

int main(int argc, char **argv) {
    const int repeats = bench_repeats(argc, argv);
    double *qs = bench_configs(BENCH_N, 7, bench_panda_lower, bench_panda_upper, BENCH_SEED);
    double M[8], P[5], J[42];
    double *Mb = (double *)malloc(sizeof(double) * 8 * BENCH_N);
    double *Pb = (double *)malloc(sizeof(double) * 5 * BENCH_N);
    double *Jb = (double *)malloc(sizeof(double) * 42 * BENCH_N);
    const long big_n = argc > 2 ? atol(argv[2]) : 100000;
    double checksum = 0, fk_ns, fkj_ns, fk_batch_ns, fkj_batch_ns, fkj_big_ns;

    BENCH_PER_CALL(fk_ns, repeats, BENCH_N, qs, 7, q, {
        panda_point_arm0_fk(q, M, P);
        bench_clobber(P);
        checksum += P[1];
    });
    BENCH_PER_CALL(fkj_ns, repeats, BENCH_N, qs, 7, q, {
        panda_point_arm0_fk_jacobian(q, M, P, J);
        bench_clobber(J);
        checksum += P[1] + J[41];
    });
    BENCH_BATCH(fk_batch_ns, repeats, BENCH_N, {
        panda_point_arm0_fk_batch(BENCH_N, qs, Mb, Pb);
        bench_clobber(Pb);
        checksum += Pb[5 * BENCH_N - 1];
    });
    BENCH_BATCH(fkj_batch_ns, repeats, BENCH_N, {
        panda_point_arm0_fk_jacobian_batch(BENCH_N, qs, Mb, Pb, Jb);
        bench_clobber(Jb);
        checksum += Pb[5 * BENCH_N - 1] + Jb[42 * BENCH_N - 1];
    });
    free(Mb); free(Pb); free(Jb);

    double *qb = bench_configs(big_n, 7, bench_panda_lower, bench_panda_upper, BENCH_SEED + 1);
    Mb = (double *)malloc(sizeof(double) * 8 * (size_t)big_n);
    Pb = (double *)malloc(sizeof(double) * 5 * (size_t)big_n);
    Jb = (double *)malloc(sizeof(double) * 42 * (size_t)big_n);
    BENCH_BATCH(fkj_big_ns, 5, big_n, {
        panda_point_arm0_fk_jacobian_batch(big_n, qb, Mb, Pb, Jb);
        bench_clobber(Jb);
        checksum += Pb[5 * big_n - 1] + Jb[42 * big_n - 1];
    });
    /* the same batches in the column layout (element k of sample s at [k * ld + s]), 64-byte aligned */
    double fkj_cols_ns, fkj_cols_big_ns;
    for (int big = 0; big < 2; ++big) {
        const long n = big ? big_n : BENCH_N, ld = (n + 7) / 8 * 8;
        const double *src = big ? qb : qs;
        double *qc, *Mc, *Pc, *Jc;
        if (posix_memalign((void **)&qc, 64, sizeof(double) * 7 * ld) ||
            posix_memalign((void **)&Mc, 64, sizeof(double) * 8 * ld) ||
            posix_memalign((void **)&Pc, 64, sizeof(double) * 5 * ld) ||
            posix_memalign((void **)&Jc, 64, sizeof(double) * 42 * ld)) return 1;
        for (long s = 0; s < n; ++s)
            for (int k = 0; k < 7; ++k) qc[k * ld + s] = src[7 * s + k];
        BENCH_BATCH(*(big ? &fkj_cols_big_ns : &fkj_cols_ns), big ? 5 : repeats, n, {
            panda_point_arm0_fk_jacobian_batch_columns(n, ld, qc, Mc, Pc, Jc);
            bench_clobber(Jc);
            checksum += Pc[4 * ld + n - 1] + Jc[41 * ld + n - 1];
        });
        free(qc); free(Mc); free(Pc); free(Jc);
    }
    free(qb);

    panda_point_arm0_fk_jacobian(qs, M, P, J);
    bench_json_begin();
    bench_json_num("fk_ns", fk_ns);
    bench_json_num("fk_jacobian_ns", fkj_ns);
    bench_json_num("fk_batch_ns", fk_batch_ns);
    bench_json_num("fk_jacobian_batch_ns", fkj_batch_ns);
    bench_json_num("fk_jacobian_batch_big_ns", fkj_big_ns);
    bench_json_num("fk_jacobian_batch_columns_ns", fkj_cols_ns);
    bench_json_num("fk_jacobian_batch_columns_big_ns", fkj_cols_big_ns);
    bench_json_num("big_n", (double)big_n);
    printf(", \"P0\": [");
    for (int k = 0; k < 5; ++k) printf("%s%.17g", k ? ", " : "", P[k]);
    printf("], \"J0\": [");
    for (int k = 0; k < 42; ++k) printf("%s%.17g", k ? ", " : "", J[k]);
    printf("], ");
    bench_json_first_ = 1;
    bench_json_end(checksum);
    free(qs); free(Mb); free(Pb); free(Jb);
    return 0;
}
