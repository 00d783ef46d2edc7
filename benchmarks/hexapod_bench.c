/* Times the hexapod's generated C (hexapod.c) and the FK + J peers (hexapod_fkj.c, built by
 * benchmarks/hexapod.py through gagen.compile) in plain C loops, with harness.h.
 *
 *   hexapod_bench INPUTS [REPEATS]
 *
 * INPUTS is a file of doubles written by hexapod.py: a header (n_call, n_batch, n_body, n_dls, damping,
 * tolerance, max_iterations, the neutral q[3]), then n_batch leg configurations q[3] (FK inputs),
 * n_batch body-frame toe targets [3] of front_left (IK inputs), n_body body poses [8] with their world
 * toe targets [18], and n_dls targets [3] for the DLS solves. Per-call timings use the first n_call
 * samples; batches use all n_batch. Prints one JSON object (ns per evaluation, medians), read by
 * hexapod.py, plus a checksum so nothing is optimised away.
 */
#include "harness.h" /* first: it sets _POSIX_C_SOURCE */

#include <math.h>
#include <stdio.h>

#include "hexapod.h"
#include "hexapod_fkj.h"

/* DLS steps from q0 until the error before a step is below tolerance; returns the number of steps taken */
static int dls_solve(const double *q0, const double *target, double damping, double tolerance,
                     int max_iterations, double *q, double *err) {
    double qn[3];
    q[0] = q0[0];
    q[1] = q0[1];
    q[2] = q0[2];
    for (int k = 0;; ++k) {
        hexapod_front_left_dls(q, target, &damping, qn, err);
        if (*err < tolerance || k == max_iterations) return k;
        q[0] = qn[0];
        q[1] = qn[1];
        q[2] = qn[2];
    }
}

int main(int argc, char **argv) {
    long count = 0;
    double *in = argc > 1 ? bench_read_doubles(argv[1], &count) : NULL;
    if (!in || count < 10) {
        fprintf(stderr, "usage: %s INPUTS [REPEATS]\n", argv[0]);
        return 2;
    }
    const int repeats = bench_repeats(argc - 1, argv + 1);
    const long n_call = (long)in[0], n_batch = (long)in[1], n_body = (long)in[2], n_dls = (long)in[3];
    const double damping = in[4], tolerance = in[5];
    const int max_iterations = (int)in[6];
    const double *neutral = in + 7;
    const double *qs = in + 10, *targets = qs + 3 * n_batch, *bodies = targets + 3 * n_batch;
    const double *dls_targets = bodies + 26 * n_body;
    if (dls_targets + 3 * n_dls != in + count || n_call > n_batch) {
        fprintf(stderr, "inputs: %ld doubles, not the layout of the header\n", count);
        return 1;
    }
    double checksum = 0, ns[16];
    double M[8], toe[5], p[3], J[9], S[18], q_up[3], q_down[3], reach, excess, q18[18], r6[6], e6[6];

    BENCH_PER_CALL(ns[0], repeats, n_call, targets, 3, t, {
        hexapod_front_left_ik(t, q_up, q_down, &reach, &excess);
        bench_clobber(q_up);
        checksum += q_up[2];
    });
    /* the floor: the IK's libm calls alone (4 atan2, 3 sqrt) on the same targets */
    BENCH_PER_CALL(ns[10], repeats, n_call, targets, 3, t, {
        double a = atan2(t[1], t[0]) + atan2(t[2], t[0]) + atan2(t[2], t[1]) + atan2(t[0], t[2]);
        a += sqrt(t[0] * t[0] + 1.0) + sqrt(t[1] * t[1] + 1.0) + sqrt(t[2] * t[2] + 1.0);
        bench_clobber(&a);
        checksum += a;
    });
    double *qb = (double *)malloc(sizeof(double) * 6 * (size_t)n_batch);
    double *aux = (double *)malloc(sizeof(double) * 2 * (size_t)n_batch);
    BENCH_BATCH(ns[1], repeats, n_batch, {
        hexapod_front_left_ik_batch(n_batch, targets, qb, qb + 3 * n_batch, aux, aux + n_batch);
        bench_clobber(qb);
        checksum += qb[3 * n_batch - 1];
    });
    BENCH_PER_CALL(ns[2], repeats, n_body, bodies, 26, b, {
        hexapod_body_ik(b, b + 8, q18, r6, e6);
        bench_clobber(q18);
        checksum += q18[17];
    });
    BENCH_PER_CALL(ns[3], repeats, n_call, qs, 3, q, {
        hexapod_front_left_fk_pga(q, M, toe, p, J, S);
        bench_clobber(J);
        checksum += J[8];
    });
    BENCH_PER_CALL(ns[4], repeats, n_call, qs, 3, q, {
        hexapod_front_left_fk_cga(q, M, toe, p, J, S);
        bench_clobber(J);
        checksum += J[8];
    });
    BENCH_PER_CALL(ns[5], repeats, n_call, qs, 3, q, {
        hexapod_fkj_front_left_pj_pga(q, p, J);
        bench_clobber(J);
        checksum += J[8];
    });
    BENCH_PER_CALL(ns[6], repeats, n_call, qs, 3, q, {
        hexapod_fkj_front_left_pj_cga(q, p, J);
        bench_clobber(J);
        checksum += J[8];
    });
    BENCH_PER_CALL(ns[7], repeats, n_call, qs, 3, q, {
        hexapod_fkj_front_left_pj_matrix(q, p, J);
        bench_clobber(J);
        checksum += J[8];
    });
    /* one DLS step, then whole solves from the neutral pose to |target - p| < tolerance */
    double qn[3], err;
    BENCH_PER_CALL(ns[8], repeats, n_dls, dls_targets, 3, t, {
        hexapod_front_left_dls(neutral, t, &damping, qn, &err);
        bench_clobber(qn);
        checksum += qn[0];
    });
    long iterations = 0, unsolved = 0, most = 0;
    BENCH_PER_CALL(ns[9], repeats, n_dls, dls_targets, 3, t, {
        double q[3];
        const int k = dls_solve(neutral, t, damping, tolerance, max_iterations, q, &err);
        bench_clobber(q);
        checksum += q[1];
        iterations += k;
        unsolved += err >= tolerance;
        if (k > most) most = k;
    });
    free(qb);
    free(aux);

    bench_json_begin();
    const char *keys[] = {"ik_ns", "ik_batch_ns", "body_ik_ns", "fk_pga_ns", "fk_cga_ns", "pj_pga_ns",
                          "pj_cga_ns", "pj_matrix_ns", "dls_step_ns", "dls_solve_ns", "ik_floor_ns"};
    for (int k = 0; k < 11; ++k) bench_json_num(keys[k], ns[k]);
    /* the DLS loop ran repeats + 1 times (one warm-up) */
    bench_json_num("dls_iterations_mean", (double)iterations / (double)((repeats + 1) * n_dls));
    bench_json_num("dls_iterations_max", (double)most);
    bench_json_num("dls_unsolved", (double)unsolved / (double)(repeats + 1));
    printf(", ");
    bench_json_first_ = 1;
    bench_json_end(checksum);
    free(in);
    return 0;
}
