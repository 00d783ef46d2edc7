/* Times a planar linkage's crank steps in a plain C loop over its generated `<name>_newton_step` kernel
 * (one whole Newton iteration per call: constraints, the structured solve, retraction), with
 * harness.h. Built once per mechanism by benchmarks/linkage.py with
 *   -DLINKAGE_HEADER='"four_bar.h"' -DLINKAGE_STEP=four_bar_newton_step
 *
 *   linkage_bench INPUTS OUTPUT [REPEATS]
 *
 * INPUTS is a file of doubles written by linkage.py: a header (n_R: motor coefficients, n_steps,
 * tolerance, max_iterations), the assembled motors R0[n_R] at the initial crank angle, then the n_steps
 * crank angles. One revolution: at each angle, Newton from the previous configuration, calling the kernel
 * until the residual it returns (max |F| before its step) is below the tolerance. OUTPUT receives the
 * configurations after every step of the last revolution (n_steps × n_R doubles, for linkage.py to check
 * against the Python solver). Prints one JSON object: ns per crank step and per kernel call (medians),
 * the Newton calls per step, plus a checksum so nothing is optimised away.
 */
#include "harness.h" /* first: it sets _POSIX_C_SOURCE */

#include <math.h>
#include <stdio.h>

#include LINKAGE_HEADER

/* Newton at crank angle *theta from R (updated in place): kernel calls until the residual before a step
 * is below tolerance; returns the number of calls (the last one only confirms convergence). */
static int crank_step(double *R, double *next, int n_R, const double *theta, double tolerance,
                      int max_iterations, double *residual) {
    for (int k = 1;; ++k) {
        LINKAGE_STEP(R, theta, next, residual);
        if (*residual < tolerance || k > max_iterations) return k;
        memcpy(R, next, sizeof(double) * (size_t)n_R);
    }
}

int main(int argc, char **argv) {
    long count = 0;
    double *in = argc > 2 ? bench_read_doubles(argv[1], &count) : NULL;
    if (!in || count < 4) {
        fprintf(stderr, "usage: %s INPUTS OUTPUT [REPEATS]\n", argv[0]);
        return 2;
    }
    const int repeats = bench_repeats(argc - 2, argv + 2);
    const int n_R = (int)in[0], max_iterations = (int)in[3];
    const long n_steps = (long)in[1];
    const double tolerance = in[2];
    const double *R0 = in + 4, *angles = R0 + n_R;
    if (angles + n_steps != in + count) {
        fprintf(stderr, "inputs: %ld doubles, not the layout of the header\n", count);
        return 1;
    }
    double *R = (double *)malloc(sizeof(double) * (size_t)n_R);
    double *next = (double *)malloc(sizeof(double) * (size_t)n_R);
    double *trajectory = (double *)malloc(sizeof(double) * (size_t)(n_R * n_steps));
    double checksum = 0, residual = 0, step_ns = 0, call_ns = 0;
    long calls = 0, unconverged = 0, most = 0;

    /* whole revolutions: ns per crank step */
    BENCH_BATCH(step_ns, repeats, n_steps, {
        memcpy(R, R0, sizeof(double) * (size_t)n_R);
        calls = unconverged = 0;
        for (long i = 0; i < n_steps; ++i) {
            const int k = crank_step(R, next, n_R, angles + i, tolerance, max_iterations, &residual);
            calls += k;
            unconverged += residual >= tolerance;
            if (k > most) most = k;
            memcpy(trajectory + (long)n_R * i, R, sizeof(double) * (size_t)n_R);
        }
        bench_clobber(trajectory);
        checksum += R[0];
    });
    /* one kernel call at each converged configuration of the revolution (R from the trajectory) */
    BENCH_BATCH(call_ns, repeats, n_steps, {
        for (long i = 0; i < n_steps; ++i) {
            LINKAGE_STEP(trajectory + (long)n_R * i, angles + i, next, &residual);
            bench_clobber(next);
            checksum += next[0];
        }
    });

    FILE *out = fopen(argv[2], "wb");
    if (!out || fwrite(trajectory, sizeof(double), (size_t)(n_R * n_steps), out) != (size_t)(n_R * n_steps)) {
        fprintf(stderr, "cannot write %s\n", argv[2]);
        return 1;
    }
    fclose(out);
    bench_json_begin();
    bench_json_num("step_ns", step_ns);
    bench_json_num("call_ns", call_ns);
    bench_json_num("calls_per_step", (double)calls / (double)n_steps);
    bench_json_num("most_calls", (double)most);
    bench_json_num("unconverged", (double)unconverged);
    bench_json_num("repeats", (double)repeats);
    bench_json_end(checksum);
    free(R);
    free(next);
    free(trajectory);
    free(in);
    return 0;
}
