// One similarity impedance control step of three iiwa 14 on a circle (21 DOF) [COOP Eq. 49-52], as a
// 1 kHz torque loop would run it: the generated C kernels of generated/three_iiwas_circle (similarity,
// task, similarity_rate), Pinocchio's C++ CRBA / RNEA / gravity per arm, and the task-space algebra in
// Eigen (per-arm Cholesky of M, a 7×7 symmetric eigendecomposition for M_Sc on the controllable
// directions). The same law as gagen.control.impedance (benchmarks/impedance.py checks the torques
// against it).
//
//   impedance_step URDF STATES [REPEATS]
//
// STATES: raw float64: V_Sd (12), the gains K (7), D (7), k_n, d_n, q_rest (21), then one state after
// the other: q (21), q̇ (21). The arms stand on the floor turned about z only, so their dynamics are
// those of one iiwa model evaluated per arm (M block diagonal; gravity along the common z).
// Prints one JSON object: step_ns (median per step over REPEATS passes over the states), and tau0 (the
// torques at the first state) for the cross-check.
#include <cstdio>
#include <vector>

#include <pinocchio/multibody.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/parsers/urdf.hpp>
#include <Eigen/Dense>

extern "C" {
#include "harness.h"
#include "three_iiwas_circle.h"
}

namespace {

constexpr int kArms = 3, kArmDof = 7, kDof = kArms * kArmDof, kRows = 7, kRank = 6;
constexpr double kRcond = 1e-10;
using Vec7 = Eigen::Matrix<double, kRows, 1>;
using Mat7 = Eigen::Matrix<double, kRows, kRows>;
using VecN = Eigen::Matrix<double, kDof, 1>;
using JacG = Eigen::Matrix<double, kRows, kDof>;  // column-major, as the kernels store it
using Block = Eigen::Matrix<double, kArmDof, kArmDof>;

struct Controller {
    pinocchio::Model model;
    std::vector<pinocchio::Data> data;
    double target[12], k[7], d[7], kn, dn;
    VecN rest;

    // τ at (q, q̇); everything on the stack or in the per-arm Data: no allocation per step
    void step(const double *q_in, const double *qd_in, double *tau_out) {
        Eigen::Map<const VecN> q(q_in), qd(qd_in);
        double v_sc[12], conditioning, jg[kRows * kDof], error[kRows], jbe[kRows * kDof];
        double twist[kRows], jdot_qdot[kRows];
        three_iiwas_circle_similarity(q_in, v_sc, &conditioning, jg);
        three_iiwas_circle_task(q_in, target, error, jbe);
        three_iiwas_circle_similarity_rate(q_in, qd_in, twist, jdot_qdot);
        Eigen::Map<const JacG> J(jg);
        Eigen::Matrix<double, kDof, kRows + 2> solved;  // M⁻¹ [J_Gᵀ | C q̇ | g]
        VecN g, posture;
        for (int a = 0; a < kArms; ++a) {
            const int o = a * kArmDof;
            pinocchio::Data &pd = data[a];
            const Eigen::Matrix<double, kArmDof, 1> qa = q.segment<kArmDof>(o), va = qd.segment<kArmDof>(o);
            pinocchio::crba(model, pd, qa);
            pd.M.triangularView<Eigen::StrictlyLower>() = pd.M.transpose().triangularView<Eigen::StrictlyLower>();
            const Block m = pd.M;
            const Eigen::Matrix<double, kArmDof, 1> bias = pinocchio::nonLinearEffects(model, pd, qa, va);
            g.segment<kArmDof>(o) = pinocchio::computeGeneralizedGravity(model, pd, qa);
            Eigen::LLT<Block> llt(m);
            Eigen::Matrix<double, kArmDof, kRows + 2> rhs;
            rhs.leftCols<kRows>() = J.middleCols<kArmDof>(o).transpose();
            rhs.col(kRows) = bias - g.segment<kArmDof>(o);
            rhs.col(kRows + 1) = g.segment<kArmDof>(o);
            solved.middleRows<kArmDof>(o) = llt.solve(rhs);
            posture.segment<kArmDof>(o) = m * (kn * (rest.segment<kArmDof>(o) - qa) - dn * va) + g.segment<kArmDof>(o);
        }
        const Eigen::Matrix<double, kRows, kRows + 2> projected = J * solved;
        Eigen::SelfAdjointEigenSolver<Mat7> eigen(projected.leftCols<kRows>());
        const Vec7 &values = eigen.eigenvalues();  // ascending
        Vec7 inverse = Vec7::Zero();
        for (int i = kRows - kRank; i < kRows; ++i)
            if (values(i) > kRcond * values(kRows - 1)) inverse(i) = 1.0 / values(i);
        const Mat7 inertia = eigen.eigenvectors() * inverse.asDiagonal() * eigen.eigenvectors().transpose();
        Eigen::Map<const Vec7> e(error), v(twist), jdq(jdot_qdot), kk(k), dd(d);
        const Vec7 acceleration = kk.cwiseProduct(e) - dd.cwiseProduct(v);
        const Vec7 wrench = inertia * (acceleration + projected.col(kRows) - jdq + projected.col(kRows + 1));
        const Eigen::Matrix<double, kDof, kRows> consistent = solved.leftCols<kRows>() * inertia;
        Eigen::Map<VecN> tau(tau_out);
        tau = J.transpose() * (wrench - consistent.transpose() * posture) + posture;
    }
};

}  // namespace

int main(int argc, char **argv) {
    if (argc < 3) {
        fprintf(stderr, "usage: impedance_step URDF STATES [REPEATS]\n");
        return 2;
    }
    Controller c;
    pinocchio::urdf::buildModel(argv[1], c.model);
    if (c.model.nq != kArmDof) {
        fprintf(stderr, "expected a 7-joint arm, got %d joints\n", (int)c.model.nq);
        return 2;
    }
    c.data.assign(kArms, pinocchio::Data(c.model));
    long count = 0;
    double *raw = bench_read_doubles(argv[2], &count);
    const long header = 12 + 7 + 7 + 2 + kDof;
    if (!raw || count < header + 2 * kDof || (count - header) % (2 * kDof)) {
        fprintf(stderr, "%s: expected %ld header values and whole states of %d\n", argv[2], header, 2 * kDof);
        return 2;
    }
    double *p = raw;
    for (int i = 0; i < 12; ++i) c.target[i] = *p++;
    for (int i = 0; i < 7; ++i) c.k[i] = *p++;
    for (int i = 0; i < 7; ++i) c.d[i] = *p++;
    c.kn = *p++;
    c.dn = *p++;
    for (int i = 0; i < kDof; ++i) c.rest(i) = *p++;
    const long n = (count - header) / (2 * kDof);
    const int repeats = bench_repeats(argc - 2, argv + 2);  // argv[3], when given
    std::vector<double> tau(kDof * n), times(repeats);
    for (int r = 0; r < repeats; ++r) {
        const uint64_t start = bench_now_ns();
        for (long s = 0; s < n; ++s) c.step(p + 2 * kDof * s, p + 2 * kDof * s + kDof, &tau[kDof * s]);
        bench_clobber(tau.data());
        times[r] = (double)(bench_now_ns() - start) / (double)n;
    }
    bench_json_begin();
    bench_json_num("step_ns", bench_median(times.data(), repeats));
    bench_json_num("states", (double)n);
    printf(", \"tau0\": [");
    for (int i = 0; i < kDof; ++i) printf("%s%.17g", i ? ", " : "", tau[i]);
    printf("]");
    double checksum = 0;
    for (double t : tau) checksum += t;
    bench_json_end(checksum);
    free(raw);
    return 0;
}
