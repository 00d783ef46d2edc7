// Pinocchio C++ baseline: forward kinematics (a tip frame's placement) and its 6×nv frame Jacobian,
// timed over random configurations, median of repeated loops (harness.h). By default the Panda (run.py);
// with the options, any chain of revolute joints, e.g. one hexapod leg (benchmarks/hexapod.py).
//
//   pinocchio_fk URDF [REPEATS] [TIP_FRAME] [--keep J1,J2,...] [--configs FILE] [--aligned]
//
//   TIP_FRAME  default panda_link8
//   --keep     build the model reduced to these joints (pinocchio::buildReducedModel; every other joint
//              locked at the neutral configuration); default: all joints
//   --configs  the configurations: raw float64, one configuration of nq values after the other; default
//              BENCH_N of harness.h's stream, uniform within the model's position limits (for the Panda,
//              the same numbers as bench_panda_lower/upper)
//   --aligned  Jacobians in LOCAL_WORLD_ALIGNED (rows 0-2: the tip point's velocity, the point Jacobian)
//              instead of WORLD
//
// Prints one JSON object:
//   fk_ns               forwardKinematics + updateFramePlacement(frame)
//   fk_jacobian_ns      that + computeFrameJacobian(model, data, q, frame, REF, J)  (note that
//                       computeFrameJacobian runs its own pass over the joint placements)
//   fk_jacobian_lean_ns computeJointJacobians(model, data, q) + updateFramePlacement +
//                       getFrameJacobian(REF): the same outputs in one pass over the chain
// plus the pose and Jacobian at the first configuration (for cross-checks): q0, p0, R0 (column-major),
// J0 (column-major 6×nv, rows [v; ω]), then checksum and n_configs.
//
// Built by programs.py. Compiled without PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION, the algorithms are
// instantiated here from the headers with -O3 -march=native; with it, they are the pip wheel's
// precompiled libpinocchio_default. The wheel's libraries are built for baseline x86-64 (16-byte
// alignment); -DEIGEN_MAX_ALIGN_BYTES=16 -DEIGEN_MALLOC_ALREADY_ALIGNED=1 keep Eigen's layouts and heap
// allocator compatible with them when -march=native enables AVX/AVX-512 (without them the Model that
// buildModel fills is freed with Eigen's hand-made aligned free, and the program crashes).
//
// Parsing the URDF and timing the algorithms are independent template instantiations, so the file can be
// compiled as two objects in parallel: -DPINFK_PART=1 (the loader) and -DPINFK_PART=2 (the rest); with
// neither, it is one translation unit.
#include <cstdio>
#include <string>
#include <vector>

#include <pinocchio/multibody.hpp>

#ifndef PINFK_PART
#define PINFK_PART 0
#endif

// the URDF's model, reduced to the joints `keep` unless it is empty; false if a joint is not in it
bool pinfk_load_model(const char *urdf, const std::vector<std::string> &keep, pinocchio::Model &model);

#if PINFK_PART != 2
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/model.hpp>
#include <pinocchio/parsers/urdf.hpp>

bool pinfk_load_model(const char *urdf, const std::vector<std::string> &keep, pinocchio::Model &model) {
    if (keep.empty()) {
        pinocchio::urdf::buildModel(urdf, model);
        return true;
    }
    pinocchio::Model full;
    pinocchio::urdf::buildModel(urdf, full);
    for (const std::string &name : keep)
        if (!full.existJointName(name)) return false;
    std::vector<pinocchio::JointIndex> locked;
    for (pinocchio::JointIndex j = 1; j < (pinocchio::JointIndex)full.njoints; ++j) {
        bool kept = false;
        for (const std::string &name : keep) kept = kept || full.names[j] == name;
        if (!kept) locked.push_back(j);
    }
    model = pinocchio::buildReducedModel(full, locked, pinocchio::neutral(full));
    return true;
}
#endif

#if PINFK_PART != 1
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/jacobian.hpp>
#include <pinocchio/algorithm/kinematics.hpp>

#include "harness.h"

static std::vector<std::string> split(const std::string &s) {
    std::vector<std::string> out;
    std::string::size_type start = 0, comma;
    while ((comma = s.find(',', start)) != std::string::npos) {
        out.push_back(s.substr(start, comma - start));
        start = comma + 1;
    }
    out.push_back(s.substr(start));
    return out;
}

// n configurations of nq doubles from a raw float64 file (malloc'd), or NULL
static double *read_configs(const char *path, int nq, long *n) {
    FILE *f = std::fopen(path, "rb");
    if (!f) return NULL;
    std::fseek(f, 0, SEEK_END);
    const long count = std::ftell(f) / (long)sizeof(double);
    std::fseek(f, 0, SEEK_SET);
    *n = count / nq;
    double *qs = (double *)std::malloc(sizeof(double) * (size_t)(*n * nq + 1));
    const bool ok = *n > 0 && count == *n * nq &&
                    std::fread(qs, sizeof(double), (size_t)count, f) == (size_t)count;
    std::fclose(f);
    if (!ok) std::free(qs);
    return ok ? qs : NULL;
}

int main(int argc, char **argv) {
    const char *usage =
        "usage: %s URDF [REPEATS] [TIP_FRAME] [--keep J1,J2,...] [--configs FILE] [--aligned]\n";
    int positional = 0;  // URDF, REPEATS, TIP_FRAME before the options
    while (positional + 1 < argc && positional < 3 && std::string(argv[positional + 1]).rfind("--", 0) != 0)
        ++positional;
    if (positional < 1) {
        std::fprintf(stderr, usage, argv[0]);
        return 2;
    }
    const int repeats = bench_repeats(positional, argv + 1);  // REPEATS is argv[2]
    const std::string tip = positional > 2 ? argv[3] : "panda_link8";
    std::vector<std::string> keep;
    const char *configs = NULL;
    pinocchio::ReferenceFrame ref = pinocchio::WORLD;
    for (int a = positional + 1; a < argc; ++a) {
        const std::string opt = argv[a];
        if (opt == "--keep" && a + 1 < argc) keep = split(argv[++a]);
        else if (opt == "--configs" && a + 1 < argc) configs = argv[++a];
        else if (opt == "--aligned") ref = pinocchio::LOCAL_WORLD_ALIGNED;
        else {
            std::fprintf(stderr, usage, argv[0]);
            return 2;
        }
    }

    pinocchio::Model model;
    if (!pinfk_load_model(argv[1], keep, model)) {
        std::fprintf(stderr, "--keep: a joint is not in %s\n", argv[1]);
        return 1;
    }
    pinocchio::Data data(model);
    const int nq = model.nq, nv = model.nv;
    if (nq < 1 || nq != nv || !model.existFrame(tip)) {
        std::fprintf(stderr, "expected a model of revolute joints (nq = nv) with a frame %s\n", tip.c_str());
        return 1;
    }
    const pinocchio::FrameIndex frame = model.getFrameId(tip);
    pinocchio::Data::Matrix6x J = pinocchio::Data::Matrix6x::Zero(6, nv);

    long n = BENCH_N;
    double *qs;
    if (configs) {
        qs = read_configs(configs, nq, &n);
        if (!qs) {
            std::fprintf(stderr, "--configs %s: not n × %d float64\n", configs, nq);
            return 1;
        }
    } else {
        const Eigen::VectorXd lo = model.lowerPositionLimit, hi = model.upperPositionLimit;
        qs = bench_configs(n, nq, lo.data(), hi.data(), BENCH_SEED);
    }
    typedef Eigen::Map<const Eigen::VectorXd> ConstMap;
    double checksum = 0, fk_ns, fkj_ns, lean_ns;

    BENCH_PER_CALL(fk_ns, repeats, n, qs, nq, q, {
        pinocchio::forwardKinematics(model, data, ConstMap(q, nq));
        pinocchio::updateFramePlacement(model, data, frame);
        bench_clobber(&data.oMf[frame]);
        checksum += data.oMf[frame].translation()[0];
    });
    BENCH_PER_CALL(fkj_ns, repeats, n, qs, nq, q, {
        pinocchio::forwardKinematics(model, data, ConstMap(q, nq));
        pinocchio::updateFramePlacement(model, data, frame);
        pinocchio::computeFrameJacobian(model, data, ConstMap(q, nq), frame, ref, J);
        bench_clobber(J.data());
        bench_clobber(&data.oMf[frame]);
        checksum += data.oMf[frame].translation()[0] + J(0, nv - 1);
    });
    BENCH_PER_CALL(lean_ns, repeats, n, qs, nq, q, {
        pinocchio::computeJointJacobians(model, data, ConstMap(q, nq));
        pinocchio::updateFramePlacement(model, data, frame);
        pinocchio::getFrameJacobian(model, data, frame, ref, J);
        bench_clobber(J.data());
        bench_clobber(&data.oMf[frame]);
        checksum += data.oMf[frame].translation()[0] + J(0, nv - 1);
    });

    // first configuration's results, for cross-checking the other methods
    pinocchio::forwardKinematics(model, data, ConstMap(qs, nq));
    pinocchio::updateFramePlacement(model, data, frame);
    J.setZero();
    pinocchio::computeFrameJacobian(model, data, ConstMap(qs, nq), frame, ref, J);
    const pinocchio::SE3 &pose = data.oMf[frame];

    bench_json_begin();
    bench_json_num("fk_ns", fk_ns);
    bench_json_num("fk_jacobian_ns", fkj_ns);
    bench_json_num("fk_jacobian_lean_ns", lean_ns);
    std::printf(", \"q0\": [");
    for (int j = 0; j < nq; ++j) std::printf("%s%.17g", j ? ", " : "", qs[j]);
    std::printf("], \"p0\": [%.17g, %.17g, %.17g]", pose.translation()[0], pose.translation()[1],
                pose.translation()[2]);
    std::printf(", \"R0\": [");  // column-major
    for (int k = 0; k < 9; ++k) std::printf("%s%.17g", k ? ", " : "", pose.rotation()(k % 3, k / 3));
    std::printf("], \"J0\": [");  // column-major 6×nv, rows [v; ω]
    for (int k = 0; k < 6 * nv; ++k) std::printf("%s%.17g", k ? ", " : "", J(k % 6, k / 6));
    std::printf("]");
    std::printf(", ");
    bench_json_first_ = 1;
    bench_json_num("checksum", checksum);  // as bench_json_end, with the number of configurations used
    bench_json_num("n_configs", (double)n);
    std::printf("}\n");
    std::free(qs);
    return 0;
}
#endif
