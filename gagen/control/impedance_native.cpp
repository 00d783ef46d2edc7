// One similarity impedance control step [COOP Eq. 49-52] of any cooperative system, in C++: the law of
// gagen.control.impedance (ImpedanceController) with the system's generated C kernels (similarity,
// task, similarity_rate, called through their addresses) and Pinocchio's CRBA / RNEA / gravity on the
// system's own model, followed by the task-space algebra of gagen.dynamics.task_space in Eigen.
// gagen.control.impedance_native compiles it and calls it through ctypes.
//
// The model is SystemDynamics.model (every chain and robot as Python built it: base placements, reduced
// URDF models, inertias, gravity), rebuilt here joint by joint from its numbers: each joint's parent,
// type, placement, body inertia and armature, exactly (Pinocchio's own serialization cannot be
// compiled with GCC 12, and its model is all the dynamics read). joints[i] says where the system's
// joint i lives in it: its velocity index, configuration index and configuration size (1, or 2 for a
// continuous joint's (cos q, sin q)). The kernels take q in the system's order; everything in between
// runs in Pinocchio's order.
//
// M⁻¹ comes from Pinocchio's sparse (tree) Cholesky, so the arms of a system stay independent blocks
// without this code knowing about arms. A handle owns all its scratch (no allocation per step); it
// is not reentrant: one handle per thread (gagen_impedance_clone).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <exception>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Dense>
#include <pinocchio/algorithm/cholesky.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody.hpp>

namespace {

constexpr int kRows = 7;  // the similarity bivector rows e12 e13 e23 e0∞ e1∞ e2∞ e3∞
constexpr int kVersor = 12;

// the generated kernels' C signatures (inputs, then outputs; matrices column-major)
typedef void (*Similarity)(const double *q, double *v_sc, double *conditioning, double *j_g);
typedef void (*Task)(const double *q, const double *v_sd, double *error, double *j_be);
typedef void (*Rate)(const double *q, const double *qd, double *twist, double *jdot_qdot);

using Vec7 = Eigen::Matrix<double, kRows, 1>;
using Mat7 = Eigen::Matrix<double, kRows, kRows>;
using Rows7 = Eigen::Matrix<double, kRows, Eigen::Dynamic>;
using Solved = Eigen::Matrix<double, Eigen::Dynamic, kRows + 2, Eigen::RowMajor>;  // rows: the solve's unit

enum Status { kOk = 0, kBadQ = 1, kBadQd = 2, kDegenerate = 3, kNotFinite = 4 };

bool finite(const double *x, int n) {
  for (int i = 0; i < n; ++i)
    if (!std::isfinite(x[i])) return false;
  return true;
}

struct Impedance {
  pinocchio::Model model;
  pinocchio::Data data;
  int n = 0, rank = 0;
  double rcond = 0.0;
  Similarity similarity = nullptr;
  Task task = nullptr;
  Rate rate = nullptr;
  std::vector<int> v_index, q_index, q_count;

  // the law's parameters (gagen_impedance_configure)
  double target[kVersor] = {0};
  Vec7 stiffness = Vec7::Zero(), damping = Vec7::Zero();
  double posture_stiffness = 0.0, posture_damping = 0.0;
  bool gravity_nullspace = true;
  Eigen::VectorXd rest;  // q_rest in Pinocchio's velocity order

  // scratch, sized once
  Eigen::VectorXd config, velocity, g, posture, tau;
  Rows7 j_g, j_be, j_pin;
  Solved solved;
  std::vector<Eigen::Vector3d> fall;  // −gravity in each joint's frame (the universe's first)

  Impedance(const pinocchio::Model &m) : model(m), data(m) {}
  Impedance(const Impedance &other) : Impedance(other.model) {
    n = other.n;
    rank = other.rank;
    rcond = other.rcond;
    similarity = other.similarity;
    task = other.task;
    rate = other.rate;
    v_index = other.v_index;
    q_index = other.q_index;
    q_count = other.q_count;
    std::memcpy(target, other.target, sizeof target);
    stiffness = other.stiffness;
    damping = other.damping;
    posture_stiffness = other.posture_stiffness;
    posture_damping = other.posture_damping;
    gravity_nullspace = other.gravity_nullspace;
    rest = other.rest;
    allocate();
  }

  void allocate() {
    config = pinocchio::neutral(model);
    velocity.setZero(n);
    g.setZero(n);
    posture.setZero(n);
    tau.setZero(n);
    j_g.setZero(kRows, n);
    j_be.setZero(kRows, n);
    j_pin.setZero(kRows, n);
    solved.setZero(n, kRows + 2);
    fall.assign(model.njoints, -model.gravity.linear());
    if (rest.size() != n) rest.setZero(n);
  }

  // q (system order) -> Pinocchio's configuration; q̇ -> its velocity
  void to_pinocchio(const double *q, const double *qd) {
    for (int i = 0; i < n; ++i) {
      if (q_count[i] == 1) {
        config[q_index[i]] = q[i];
      } else {
        config[q_index[i]] = std::cos(q[i]);
        config[q_index[i] + 1] = std::sin(q[i]);
      }
      velocity[v_index[i]] = qd[i];
    }
  }

  // g(q) from CRBA's composite inertias (one RNEA pass fewer): at rest every body accelerates by −gravity
  // (a linear acceleration: SystemDynamics' gravity has no angular part), so the force across joint i
  // is Ycrb_i (−gravity in frame i), and g_i its power on S_i; CRBA (LOCAL convention) leaves Ycrb_i S_i
  // in column i of Fcrb[i]. −gravity in frame i: rotated down the tree by each liMi.
  void gravity_from_crba() {
    for (pinocchio::JointIndex j = 1; j < static_cast<pinocchio::JointIndex>(model.njoints); ++j) {
      fall[j].noalias() = data.liMi[j].rotation().transpose() * fall[model.parents[j]];
      const int v = model.idx_vs[j];
      g[v] = data.Fcrb[j].col(v).head<3>().dot(fall[j]);
    }
  }

  // x ← M⁻¹ x with M = U D Uᵀ from cholesky::decompose: Pinocchio's sparse (tree) solve, on all the
  // columns at once rather than one after the other
  void solve(Solved &x) const {
    const Eigen::MatrixXd &U = data.U;
    const std::vector<int> &subtree = data.nvSubtree_fromRow;
    for (int k = n - 2; k >= 0; --k) {
      const int m = subtree[k] - 1;
      if (m) x.row(k) -= U.row(k).segment(k + 1, m).lazyProduct(x.middleRows(k + 1, m));
    }
    x = data.Dinv.asDiagonal() * x;
    for (int k = 0; k < n - 1; ++k) {
      const int m = subtree[k] - 1;
      if (m) x.middleRows(k + 1, m) -= U.row(k).segment(k + 1, m).transpose().lazyProduct(x.row(k));
    }
  }

  int step(const double *q, const double *qd, double *tau_out, double *error, double *twist,
           double *conditioning) {
    if (!finite(q, n)) return kBadQ;  // checked before any kernel reads them
    if (!finite(qd, n)) return kBadQd;
    double v_sc[kVersor], jdot_qdot[kRows];
    similarity(q, v_sc, conditioning, j_g.data());
    if (!(*conditioning > 0)) return kDegenerate;
    task(q, target, error, j_be.data());
    rate(q, qd, twist, jdot_qdot);

    to_pinocchio(q, qd);
    for (int i = 0; i < n; ++i) j_pin.col(v_index[i]) = j_g.col(i);
    // joint space: M (upper triangle, then mirrored for products), C q̇ + g, g; M = U D Uᵀ
    pinocchio::crba(model, data, config, pinocchio::Convention::LOCAL);
    gravity_from_crba();
    data.M.triangularView<Eigen::StrictlyLower>() = data.M.transpose().triangularView<Eigen::StrictlyLower>();
    pinocchio::cholesky::decompose(model, data);
    pinocchio::nonLinearEffects(model, data, config, velocity);
    // one solve with M for M⁻¹ [J_Gᵀ | C q̇ | g]
    solved.leftCols<kRows>() = j_pin.transpose();
    solved.col(kRows) = data.nle - g;
    solved.col(kRows + 1) = g;
    solve(solved);
    const Eigen::Matrix<double, kRows, kRows + 2> projected = j_pin.lazyProduct(solved);  // [A | J M⁻¹ C q̇ | J M⁻¹ g]

    // M_Sc: the inverse of A on its ``rank`` largest eigenvalues (those above rcond × the largest)
    Eigen::SelfAdjointEigenSolver<Mat7> eigen(projected.leftCols<kRows>());
    const Vec7 &values = eigen.eigenvalues();  // ascending
    const double floor = rcond * std::max(values(kRows - 1), 0.0);
    Vec7 inverse = Vec7::Zero();
    for (int k = kRows - rank; k < kRows; ++k)
      if (values(k) > floor) inverse(k) = 1.0 / values(k);
    const Mat7 &u = eigen.eigenvectors();
    const Mat7 inertia = u * inverse.asDiagonal() * u.transpose();

    // W_Sd = M_Sc V̇_Sd + C_Sc + g_Sc, V̇_Sd = K B_S,e − D V_S
    Eigen::Map<const Vec7> e(error), v(twist), jdq(jdot_qdot);
    const Vec7 acceleration = stiffness.cwiseProduct(e) - damping.cwiseProduct(v);
    const Vec7 wrench = inertia * acceleration + inertia * (projected.col(kRows) - jdq) +
                        inertia * projected.col(kRows + 1);
    // posture M (k_n (q_rest − q) − d_n q̇) [+ g], through Nᵀ = I − J_Gᵀ J̄ᵀ, J̄ = M⁻¹ J_Gᵀ M_Sc
    for (int i = 0; i < n; ++i) tau[v_index[i]] = posture_stiffness * (rest[v_index[i]] - q[i]);
    tau -= posture_damping * velocity;
    posture.noalias() = data.M * tau;
    if (gravity_nullspace) posture += g;
    const Vec7 projected_posture = inertia * (solved.leftCols<kRows>().transpose() * posture);
    tau = posture;
    tau.noalias() += j_pin.transpose() * (wrench - projected_posture);
    for (int i = 0; i < n; ++i) tau_out[i] = tau[v_index[i]];
    return finite(tau_out, n) ? kOk : kNotFinite;
  }
};

void say(char *message, long size, const std::string &text) {
  if (message && size > 0) {
    std::strncpy(message, text.c_str(), static_cast<size_t>(size - 1));
    message[size - 1] = '\0';
  }
}

// One joint of the model description: the joint types SystemDynamics allows (one velocity each).
constexpr int kJointDoubles = 29;  // R (9, row-major), p (3); mass, lever (3), inertia (9); axis (3); armature

pinocchio::JointModel joint_of(int type, const Eigen::Vector3d &axis) {
  switch (type) {
    case 0: return pinocchio::JointModelRX();
    case 1: return pinocchio::JointModelRY();
    case 2: return pinocchio::JointModelRZ();
    case 3: return pinocchio::JointModelRevoluteUnaligned(axis);
    case 4: return pinocchio::JointModelRUBX();
    case 5: return pinocchio::JointModelRUBY();
    case 6: return pinocchio::JointModelRUBZ();
    case 7: return pinocchio::JointModelRevoluteUnboundedUnaligned(axis);
    case 8: return pinocchio::JointModelPX();
    case 9: return pinocchio::JointModelPY();
    case 10: return pinocchio::JointModelPZ();
    case 11: return pinocchio::JointModelPrismaticUnaligned(axis);
    default: throw std::invalid_argument("joint type code " + std::to_string(type) + " is not supported");
  }
}

// count joints after the universe: ints (parent, type) and kJointDoubles doubles each; gravity (6)
pinocchio::Model build_model(int count, const int *ints, const double *doubles, const double *gravity) {
  pinocchio::Model model;
  model.gravity = pinocchio::Motion(Eigen::Map<const Eigen::Vector3d>(gravity),
                                    Eigen::Map<const Eigen::Vector3d>(gravity + 3));
  std::vector<double> armature;
  for (int j = 0; j < count; ++j) {
    const int parent = ints[2 * j], type = ints[2 * j + 1];
    if (parent < 0 || parent > j) throw std::invalid_argument("joint " + std::to_string(j + 1) + ": parent " +
                                                              std::to_string(parent) + " is not an earlier joint");
    const double *d = doubles + kJointDoubles * j;
    const Eigen::Matrix3d rotation = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(d);
    const pinocchio::SE3 placement(rotation, Eigen::Map<const Eigen::Vector3d>(d + 9));
    const Eigen::Matrix3d inertia = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(d + 16);
    const auto id = model.addJoint(static_cast<pinocchio::JointIndex>(parent),
                                   joint_of(type, Eigen::Map<const Eigen::Vector3d>(d + 25)), placement,
                                   "joint" + std::to_string(j + 1));
    model.inertias[id] = pinocchio::Inertia(d[12], Eigen::Map<const Eigen::Vector3d>(d + 13),
                                            pinocchio::Symmetric3(inertia));
    armature.push_back(d[28]);
  }
  model.armature = Eigen::Map<const Eigen::VectorXd>(armature.data(), static_cast<Eigen::Index>(armature.size()));
  return model;
}

}  // namespace

extern "C" {

// A handle, or null with the reason in ``message``. The model: see build_model. joints: 3 × dof ints
// (velocity index, configuration index, configuration size per system joint).
void *gagen_impedance_create(int model_joints, const int *model_ints, const double *model_doubles,
                             const double *gravity, int dof, const int *joints,
                             std::uintptr_t similarity, std::uintptr_t task, std::uintptr_t rate, int rank,
                             double rcond, char *message, long message_size) {
  try {
    if (!similarity || !task || !rate) throw std::invalid_argument("a kernel address of 0");
    if (rank < 1 || rank > kRows) throw std::invalid_argument("rank must be between 1 and 7");
    const pinocchio::Model model = build_model(model_joints, model_ints, model_doubles, gravity);
    if (!model.gravity.angular().isZero(0.0)) throw std::invalid_argument("gravity with an angular part");
    if (model.nv != dof)
      throw std::invalid_argument("the model has " + std::to_string(model.nv) + " velocities, the system " +
                                  std::to_string(dof) + " joints");
    auto self = std::make_unique<Impedance>(model);
    self->n = dof;
    self->rank = rank;
    self->rcond = rcond;
    self->similarity = reinterpret_cast<Similarity>(similarity);
    self->task = reinterpret_cast<Task>(task);
    self->rate = reinterpret_cast<Rate>(rate);
    std::vector<bool> seen(static_cast<size_t>(dof), false);
    for (int i = 0; i < dof; ++i) {
      const int v = joints[3 * i], q = joints[3 * i + 1], count = joints[3 * i + 2];
      if (v < 0 || v >= dof || seen[v] || (count != 1 && count != 2) || q < 0 || q + count > model.nq) {
        throw std::invalid_argument("joint " + std::to_string(i) + ": velocity index " + std::to_string(v) +
                                    ", configuration " + std::to_string(q) + " + " + std::to_string(count) +
                                    " do not fit the model (or repeat another joint's)");
      }
      seen[v] = true;
      self->v_index.push_back(v);
      self->q_index.push_back(q);
      self->q_count.push_back(count);
    }
    self->allocate();
    return self.release();
  } catch (const std::exception &e) {
    say(message, message_size, e.what());
    return nullptr;
  }
}

void *gagen_impedance_clone(const void *handle) {
  try {
    return new Impedance(*static_cast<const Impedance *>(handle));
  } catch (const std::exception &) {
    return nullptr;
  }
}

// V_Sd (12), K (7), D (7), k_n, d_n, whether g goes through the nullspace, q_rest (dof, system order)
void gagen_impedance_configure(void *handle, const double *target, const double *stiffness,
                               const double *damping, double posture_stiffness, double posture_damping,
                               int gravity_nullspace, const double *rest) {
  auto *self = static_cast<Impedance *>(handle);
  std::memcpy(self->target, target, sizeof self->target);
  self->stiffness = Eigen::Map<const Vec7>(stiffness);
  self->damping = Eigen::Map<const Vec7>(damping);
  self->posture_stiffness = posture_stiffness;
  self->posture_damping = posture_damping;
  self->gravity_nullspace = gravity_nullspace != 0;
  for (int i = 0; i < self->n; ++i) self->rest[self->v_index[i]] = rest[i];
}

// io: q (dof), q̇ (dof) in; τ (dof), B_S,e (7), V_S (7), the conditioning (1) out. 0, or a Status.
int gagen_impedance_step(void *handle, double *io) {
  auto *self = static_cast<Impedance *>(handle);
  const int n = self->n;
  return self->step(io, io + n, io + 2 * n, io + 3 * n, io + 3 * n + kRows, io + 3 * n + 2 * kRows);
}

void gagen_impedance_destroy(void *handle) { delete static_cast<Impedance *>(handle); }

}  // extern "C"
