/* Times CasADi's generated C for the 4×4 matrix chain (matrix_chain.py --emit) with harness.h.
 *
 *   matrix_chain_bench [REPEATS]
 *
 * Prints one JSON object: fk_ns (mc_fk: R, p), fk_jacobian_ns (mc_fk_jacobian: R, p and the 6×7 WORLD
 * Jacobian), fk_jacobian_geo_ns (the tip-velocity Jacobian instead), and the first configuration's p and J
 * for run.py's cross-check. Calls go through CasADi's own entry points (arg/res pointer arrays).
 * sincos7_ns is the floor every method shares: sin and cos of the 7 joint values (libm; gcc fuses each
 * pair into one sincos call) and nothing else.
 */
#include "harness.h" /* first: it sets _POSIX_C_SOURCE */

#include <math.h>
#include <stdio.h>

#include "matrix_chain.h"

int main(int argc, char **argv) {
    const int repeats = bench_repeats(argc, argv);
    double *qs = bench_configs(BENCH_N, 7, bench_panda_lower, bench_panda_upper, BENCH_SEED);
    double R[9], p[3], J[42], w[1];
    long long iw[1];
    double checksum = 0, fk_ns, fkj_ns, geo_ns, sincos_ns, sc[14];
    const double *arg[1];
    double *res[3] = {R, p, J};

    BENCH_PER_CALL(fk_ns, repeats, BENCH_N, qs, 7, q, {
        arg[0] = q;
        mc_fk(arg, res, iw, w, 0);
        bench_clobber(p);
        checksum += p[0];
    });
    BENCH_PER_CALL(fkj_ns, repeats, BENCH_N, qs, 7, q, {
        arg[0] = q;
        mc_fk_jacobian(arg, res, iw, w, 0);
        bench_clobber(J);
        checksum += p[0] + J[41];
    });
    BENCH_PER_CALL(geo_ns, repeats, BENCH_N, qs, 7, q, {
        arg[0] = q;
        mc_fk_jacobian_geo(arg, res, iw, w, 0);
        bench_clobber(J);
        checksum += p[0] + J[41];
    });

    BENCH_PER_CALL(sincos_ns, repeats, BENCH_N, qs, 7, q, {
        for (int j = 0; j < 7; ++j) {
            sc[2 * j] = sin(q[j]);
            sc[2 * j + 1] = cos(q[j]);
        }
        bench_clobber(sc);
        checksum += sc[13];
    });

    arg[0] = qs;
    mc_fk_jacobian(arg, res, iw, w, 0);
    bench_json_begin();
    bench_json_num("fk_ns", fk_ns);
    bench_json_num("fk_jacobian_ns", fkj_ns);
    bench_json_num("fk_jacobian_geo_ns", geo_ns);
    bench_json_num("sincos7_ns", sincos_ns);
    printf(", \"p0\": [%.17g, %.17g, %.17g], \"J0\": [", p[0], p[1], p[2]);
    for (int k = 0; k < 42; ++k) printf("%s%.17g", k ? ", " : "", J[k]);
    printf("], ");
    bench_json_first_ = 1;
    bench_json_end(checksum);
    free(qs);
    return 0;
}
