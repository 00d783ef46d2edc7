// Pinocchio C++ baseline: Panda forward kinematics (end-effector frame placement) and its 6×7 WORLD
// frame Jacobian, timed over BENCH_N random configurations, median of repeated loops (harness.h).
//
//   pinocchio_fk URDF [REPEATS] [TIP_FRAME]
//
// Prints one JSON object:
//   fk_ns               forwardKinematics + updateFramePlacement(frame)
//   fk_jacobian_ns      that + computeFrameJacobian(model, data, q, frame, WORLD, J)  (note that
//                       computeFrameJacobian runs its own pass over the joint placements)
//   fk_jacobian_lean_ns computeJointJacobians(model, data, q) + updateFramePlacement +
//                       getFrameJacobian(WORLD): the same outputs in one pass over the chain
// plus the pose and Jacobian at the first configuration (for run.py's cross-checks).
//
// Built by run.py. Compiled without PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION, the algorithms are
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

#include <pinocchio/multibody.hpp>

#ifndef PINFK_PART
#define PINFK_PART 0
#endif

void pinfk_load_model(const char *urdf, pinocchio::Model &model);

#if PINFK_PART != 2
#include <pinocchio/parsers/urdf.hpp>

void pinfk_load_model(const char *urdf, pinocchio::Model &model) {
    pinocchio::urdf::buildModel(urdf, model);
}
#endif

#if PINFK_PART != 1
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/jacobian.hpp>
#include <pinocchio/algorithm/kinematics.hpp>

#include "harness.h"

int main(int argc, char **argv) {
    if (argc < 2) {
        std::fprintf(stderr, "usage: %s URDF [REPEATS] [TIP_FRAME]\n", argv[0]);
        return 2;
    }
    const int repeats = bench_repeats(argc, argv);
    const std::string tip = argc > 3 ? argv[3] : "panda_link8";

    pinocchio::Model model;
    pinfk_load_model(argv[1], model);
    pinocchio::Data data(model);
    if (model.nq != 7 || model.nv != 7 || !model.existFrame(tip)) {
        std::fprintf(stderr, "expected a 7-DOF model with a frame %s\n", tip.c_str());
        return 1;
    }
    const pinocchio::FrameIndex frame = model.getFrameId(tip);
    pinocchio::Data::Matrix6x J = pinocchio::Data::Matrix6x::Zero(6, model.nv);

    double *qs = bench_configs(BENCH_N, 7, bench_panda_lower, bench_panda_upper, BENCH_SEED);
    typedef Eigen::Map<const Eigen::VectorXd> ConstMap;
    double checksum = 0, fk_ns, fkj_ns, lean_ns;

    BENCH_PER_CALL(fk_ns, repeats, BENCH_N, qs, 7, q, {
        pinocchio::forwardKinematics(model, data, ConstMap(q, 7));
        pinocchio::updateFramePlacement(model, data, frame);
        bench_clobber(&data.oMf[frame]);
        checksum += data.oMf[frame].translation()[0];
    });
    BENCH_PER_CALL(fkj_ns, repeats, BENCH_N, qs, 7, q, {
        pinocchio::forwardKinematics(model, data, ConstMap(q, 7));
        pinocchio::updateFramePlacement(model, data, frame);
        pinocchio::computeFrameJacobian(model, data, ConstMap(q, 7), frame, pinocchio::WORLD, J);
        bench_clobber(J.data());
        bench_clobber(&data.oMf[frame]);
        checksum += data.oMf[frame].translation()[0] + J(0, 6);
    });
    BENCH_PER_CALL(lean_ns, repeats, BENCH_N, qs, 7, q, {
        pinocchio::computeJointJacobians(model, data, ConstMap(q, 7));
        pinocchio::updateFramePlacement(model, data, frame);
        pinocchio::getFrameJacobian(model, data, frame, pinocchio::WORLD, J);
        bench_clobber(J.data());
        bench_clobber(&data.oMf[frame]);
        checksum += data.oMf[frame].translation()[0] + J(0, 6);
    });

    // first configuration's results, for cross-checking the other methods
    pinocchio::forwardKinematics(model, data, ConstMap(qs, 7));
    pinocchio::updateFramePlacement(model, data, frame);
    J.setZero();
    pinocchio::computeFrameJacobian(model, data, ConstMap(qs, 7), frame, pinocchio::WORLD, J);
    const pinocchio::SE3 &pose = data.oMf[frame];

    bench_json_begin();
    bench_json_num("fk_ns", fk_ns);
    bench_json_num("fk_jacobian_ns", fkj_ns);
    bench_json_num("fk_jacobian_lean_ns", lean_ns);
    std::printf(", \"q0\": [");
    for (int j = 0; j < 7; ++j) std::printf("%s%.17g", j ? ", " : "", qs[j]);
    std::printf("], \"p0\": [%.17g, %.17g, %.17g]", pose.translation()[0], pose.translation()[1],
                pose.translation()[2]);
    std::printf(", \"R0\": [");  // column-major
    for (int k = 0; k < 9; ++k) std::printf("%s%.17g", k ? ", " : "", pose.rotation()(k % 3, k / 3));
    std::printf("], \"J0\": [");  // column-major 6×7, rows [v; ω]
    for (int k = 0; k < 42; ++k) std::printf("%s%.17g", k ? ", " : "", J(k % 6, k / 6));
    std::printf("]");
    std::printf(", ");
    bench_json_first_ = 1;
    bench_json_end(checksum);
    free(qs);
    return 0;
}
#endif
