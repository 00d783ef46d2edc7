/* Times a stereo rig's generated per-frame `<rig>_estimate` kernel (two image lines and two image mass
 * centres -> the 3D symmetry axis, its conditioning, the mass centre and the position reference) in a
 * plain C loop, single calls and the batched form, with harness.h. Built by benchmarks/stereo.py with
 *   -DSTEREO_HEADER='"stereo_rig.h"' -DSTEREO_ESTIMATE=stereo_rig_estimate
 *
 *   stereo_bench INPUTS [REPEATS]
 *
 * INPUTS: n observations of 8 doubles (theta_l, r_l, theta_r, r_r, x_l, y_l, x_r, y_r), written by
 * stereo.py. Prints one JSON object: ns per single call and per observation in the batch (medians).
 */
#include "harness.h" /* first: it sets _POSIX_C_SOURCE */

#include STEREO_HEADER

#define GLUE_(a, b) a##b
#define GLUE(a, b) GLUE_(a, b)
#define STEREO_BATCH GLUE(STEREO_ESTIMATE, _batch)

int main(int argc, char **argv) {
    long count = 0;
    double *obs = argc > 1 ? bench_read_doubles(argv[1], &count) : NULL;
    if (!obs || count < 8 || count % 8) {
        fprintf(stderr, "usage: %s INPUTS [REPEATS] (INPUTS: n x 8 doubles)\n", argv[0]);
        return 2;
    }
    const long n = count / 8;
    const int repeats = bench_repeats(argc - 1, argv + 1);
    /* outputs: point 3, direction 3, conditioning 1, centre 3, reference 3, gap 1 */
    double *out = (double *)malloc(sizeof(double) * 14 * (size_t)n);
    double checksum = 0, single_ns = 0, batch_ns = 0;
    double point[3], direction[3], conditioning, centre[3], reference[3], gap;
    BENCH_PER_CALL(single_ns, repeats, n, obs, 8, o, {
        STEREO_ESTIMATE(o, point, direction, &conditioning, centre, reference, &gap);
        bench_clobber(reference);
        checksum += reference[0] + conditioning;
    });
    BENCH_BATCH(batch_ns, repeats, n, {
        STEREO_BATCH(n, obs, out, out + 3 * n, out + 6 * n, out + 7 * n, out + 10 * n, out + 13 * n);
        bench_clobber(out);
        checksum += out[0];
    });
    bench_json_begin();
    bench_json_num("single_ns", single_ns);
    bench_json_num("batch_ns", batch_ns);
    bench_json_num("observations", (double)n);
    bench_json_end(checksum);
    free(out);
    free(obs);
    return 0;
}
