/* Times gagen's generated C for the bundled three-Panda circle (generated/three_pandas_circle/) with harness.h.
 *
 *   circle_bench [REPEATS] [BIG_N]
 *
 * Configurations: 21 joint values, each arm's 7 uniform within the Panda joint limits (harness.h's stream).
 * Prints one JSON object, times in ns:
 *   similarity_ns            three_pandas_circle_similarity (V_Sc, conditioning, J_G,Sc), one call each
 *   similarity_batch_ns      ..._similarity_batch over BENCH_N configurations, per configuration
 *   similarity_batch_big_ns  ..._similarity_batch over BIG_N (default 100 000) configurations, per
 *                            configuration (median of 5 batches)
 *   primitive_ns, similarity_jacobians_ns, task_ns   the other system kernels, one call each (task's V_Sd:
 *                            V_Sc at the last configuration)
 *   arms_fk_jacobian_ns      arm0_fk_jacobian + arm1_fk_jacobian + arm2_fk_jacobian (three calls)
 * and the first configuration (q0) with its V_Sc, conditioning and J_G for run.py's check against CasADi.
 */
#include "harness.h" /* first: it sets _POSIX_C_SOURCE */

#include <stdio.h>

#include "three_pandas_circle.h"

#define DOF THREE_PANDAS_CIRCLE_SIMILARITY_Q_SIZE
#define NV THREE_PANDAS_CIRCLE_SIMILARITY_V_SC_SIZE
#define NC THREE_PANDAS_CIRCLE_SIMILARITY_CONDITIONING_SIZE
#define NJ THREE_PANDAS_CIRCLE_SIMILARITY_J_G_SIZE
#define BIG_REPEATS 5

static double *alloc(long n) { return (double *)malloc(sizeof(double) * (size_t)n); }

static void print_array(const char *key, const double *v, int n) {
    printf(", \"%s\": [", key);
    for (int k = 0; k < n; ++k) printf("%s%.17g", k ? ", " : "", v[k]);
    printf("]");
}

int main(int argc, char **argv) {
    const int repeats = bench_repeats(argc, argv);
    const long big_n = argc > 2 ? atol(argv[2]) : 100000;
    double lo[DOF], hi[DOF];
    for (int j = 0; j < DOF; ++j) {
        lo[j] = bench_panda_lower[j % 7];
        hi[j] = bench_panda_upper[j % 7];
    }
    double *qs = bench_configs(BENCH_N, DOF, lo, hi, BENCH_SEED);
    double V[NV], cond[NC], J[NJ], V_Sd[NV];
    double X_c[THREE_PANDAS_CIRCLE_PRIMITIVE_X_C_SIZE], J_c[THREE_PANDAS_CIRCLE_PRIMITIVE_J_C_SIZE];
    double J_A[THREE_PANDAS_CIRCLE_SIMILARITY_JACOBIANS_J_A_SIZE];
    double log_V[THREE_PANDAS_CIRCLE_SIMILARITY_JACOBIANS_LOG_V_SIZE];
    double J_B[THREE_PANDAS_CIRCLE_SIMILARITY_JACOBIANS_J_B_SIZE];
    double e[THREE_PANDAS_CIRCLE_TASK_E_SIZE], J_Be[THREE_PANDAS_CIRCLE_TASK_J_BE_SIZE];
    double M[3][8], P[3][5], J_S[3][42];
    double checksum = 0, sim_ns, batch_ns, big_ns, prim_ns, simj_ns, task_ns, arms_ns;

    BENCH_PER_CALL(sim_ns, repeats, BENCH_N, qs, DOF, q, {
        three_pandas_circle_similarity(q, V, cond, J);
        bench_clobber(J);
        checksum += V[0] + J[NJ - 1];
    });
    BENCH_PER_CALL(prim_ns, repeats, BENCH_N, qs, DOF, q, {
        three_pandas_circle_primitive(q, X_c, J_c);
        bench_clobber(J_c);
        checksum += X_c[0] + J_c[0];
    });
    BENCH_PER_CALL(simj_ns, repeats, BENCH_N, qs, DOF, q, {
        three_pandas_circle_similarity_jacobians(q, J_A, log_V, J_B);
        bench_clobber(J_B);
        checksum += log_V[0] + J_B[0];
    });
    three_pandas_circle_similarity(qs + DOF * (BENCH_N - 1), V_Sd, cond, J);
    BENCH_PER_CALL(task_ns, repeats, BENCH_N, qs, DOF, q, {
        three_pandas_circle_task(q, V_Sd, e, J_Be);
        bench_clobber(J_Be);
        checksum += e[0] + J_Be[0];
    });
    BENCH_PER_CALL(arms_ns, repeats, BENCH_N, qs, DOF, q, {
        three_pandas_circle_arm0_fk_jacobian(q, M[0], P[0], J_S[0]);
        three_pandas_circle_arm1_fk_jacobian(q + 7, M[1], P[1], J_S[1]);
        three_pandas_circle_arm2_fk_jacobian(q + 14, M[2], P[2], J_S[2]);
        bench_clobber(J_S);
        checksum += J_S[0][41] + J_S[1][41] + J_S[2][41];
    });

    double *Vb = alloc(NV * BENCH_N), *Cb = alloc(NC * BENCH_N), *Jb = alloc(NJ * BENCH_N);
    BENCH_BATCH(batch_ns, repeats, BENCH_N, {
        three_pandas_circle_similarity_batch(BENCH_N, qs, Vb, Cb, Jb);
        bench_clobber(Jb);
        checksum += Jb[NJ * BENCH_N - 1];
    });
    free(Vb); free(Cb); free(Jb);

    double *qb = bench_configs(big_n, DOF, lo, hi, BENCH_SEED + 1);
    Vb = alloc(NV * big_n); Cb = alloc(NC * big_n); Jb = alloc(NJ * big_n);
    BENCH_BATCH(big_ns, BIG_REPEATS, big_n, {
        three_pandas_circle_similarity_batch(big_n, qb, Vb, Cb, Jb);
        bench_clobber(Jb);
        checksum += Jb[NJ * big_n - 1];
    });
    free(qb); free(Vb); free(Cb); free(Jb);

    three_pandas_circle_similarity(qs, V, cond, J);
    bench_json_begin();
    bench_json_num("similarity_ns", sim_ns);
    bench_json_num("similarity_batch_ns", batch_ns);
    bench_json_num("similarity_batch_big_ns", big_ns);
    bench_json_num("big_n", (double)big_n);
    bench_json_num("primitive_ns", prim_ns);
    bench_json_num("similarity_jacobians_ns", simj_ns);
    bench_json_num("task_ns", task_ns);
    bench_json_num("arms_fk_jacobian_ns", arms_ns);
    print_array("q0", qs, DOF);
    print_array("V0", V, NV);
    print_array("cond0", cond, NC);
    print_array("J0", J, NJ);
    printf(", ");
    bench_json_first_ = 1;
    bench_json_end(checksum);
    free(qs);
    return 0;
}
