// A Crocoddyl residual r(x) = f(q) whose value and Jacobian come from one generated C kernel, called
// directly: no Python in the solver's loop (gagen.control.torque, KernelResidual's C++ twin).
//
// The kernel is void f(const double *q[, const double *p], double *r, double *J): q in the system's
// joint order, p an optional parameter vector held by the residual (the task kernel's V_Sd), r of nr
// rows, J = dr/dq column-major (nr x n). order[i] is the Pinocchio velocity index of joint i of the
// system. Kernels are reentrant and the scratch (q, r, J) is the call's own, so a residual may serve
// several solvers and threads at once. (Crocoddyl's wheel does not export the type information of its
// data classes, so the scratch cannot live in a data class derived from them.)
#include <boost/python.hpp>
#include <crocoddyl/core/residual-base.hpp>
#include <crocoddyl/multibody/states/multibody.hpp>

#include <cstdint>
#include <memory>
#include <stdexcept>

namespace bp = boost::python;

typedef void (*KernelWithParameter)(const double *, const double *, double *, double *);
typedef void (*Kernel)(const double *, double *, double *);

class GagenKernelResidual : public crocoddyl::ResidualModelAbstract {
 public:
  GagenKernelResidual(std::shared_ptr<crocoddyl::StateMultibody> state, std::size_t nu, std::size_t nr,
                      std::uintptr_t address, const Eigen::VectorXd &parameter, const Eigen::VectorXi &order,
                      bool has_parameter)
      : crocoddyl::ResidualModelAbstract(state, nr, nu, true, false, false),
        address_(address), parameter_(parameter), order_(order), has_parameter_(has_parameter) {
    if (address == 0) throw std::invalid_argument("a kernel address of 0");
    for (int i = 0; i < order.size(); ++i)
      if (order[i] < 0 || static_cast<std::size_t>(order[i]) >= state->get_nv())
        throw std::invalid_argument("an order index outside the state's velocity");
  }

  void calc(const std::shared_ptr<crocoddyl::ResidualDataAbstract> &data,
            const Eigen::Ref<const Eigen::VectorXd> &x, const Eigen::Ref<const Eigen::VectorXd> &) override {
    Eigen::MatrixXd jacobian(nr_, order_.size());
    Eigen::VectorXd value(nr_);
    evaluate(x, value, jacobian);
    data->r = value;
  }

  void calc(const std::shared_ptr<crocoddyl::ResidualDataAbstract> &data,
            const Eigen::Ref<const Eigen::VectorXd> &x) override {
    calc(data, x, Eigen::VectorXd::Zero(nu_));
  }

  void calcDiff(const std::shared_ptr<crocoddyl::ResidualDataAbstract> &data,
                const Eigen::Ref<const Eigen::VectorXd> &x, const Eigen::Ref<const Eigen::VectorXd> &) override {
    Eigen::MatrixXd jacobian(nr_, order_.size());  // column-major, as the kernel writes it
    Eigen::VectorXd value(nr_);
    evaluate(x, value, jacobian);
    for (int i = 0; i < order_.size(); ++i) data->Rx.col(order_[i]) = jacobian.col(i);
  }

  void calcDiff(const std::shared_ptr<crocoddyl::ResidualDataAbstract> &data,
                const Eigen::Ref<const Eigen::VectorXd> &x) override {
    calcDiff(data, x, Eigen::VectorXd::Zero(nu_));
  }

  const Eigen::VectorXd &get_parameter() const { return parameter_; }
  void set_parameter(const Eigen::VectorXd &parameter) {
    if (parameter.size() != parameter_.size()) throw std::invalid_argument("a parameter of another size");
    parameter_ = parameter;
  }

 private:
  void evaluate(const Eigen::Ref<const Eigen::VectorXd> &x, Eigen::VectorXd &value, Eigen::MatrixXd &jacobian) {
    Eigen::VectorXd q(order_.size());
    for (int i = 0; i < order_.size(); ++i) q[i] = x[order_[i]];
    if (has_parameter_)
      reinterpret_cast<KernelWithParameter>(address_)(q.data(), parameter_.data(), value.data(), jacobian.data());
    else
      reinterpret_cast<Kernel>(address_)(q.data(), value.data(), jacobian.data());
  }

  std::uintptr_t address_;
  Eigen::VectorXd parameter_;
  Eigen::VectorXi order_;
  bool has_parameter_;
};

#define GAGEN_PYTHON_MODULE(name) BOOST_PYTHON_MODULE(name)

GAGEN_PYTHON_MODULE(GAGEN_MODULE) {
  bp::import("crocoddyl");  // the base classes' converters
  typedef void (GagenKernelResidual::*Calc)(const std::shared_ptr<crocoddyl::ResidualDataAbstract> &,
                                            const Eigen::Ref<const Eigen::VectorXd> &,
                                            const Eigen::Ref<const Eigen::VectorXd> &);
  bp::class_<GagenKernelResidual, bp::bases<crocoddyl::ResidualModelAbstract>,
             std::shared_ptr<GagenKernelResidual>, boost::noncopyable>(
      "KernelResidual",
      "r(x) = f(q) and its Jacobian from a generated C kernel's address, called from C++.",
      bp::init<std::shared_ptr<crocoddyl::StateMultibody>, std::size_t, std::size_t, std::uintptr_t,
               Eigen::VectorXd, Eigen::VectorXi, bool>(
          bp::args("self", "state", "nu", "nr", "address", "parameter", "order", "has_parameter")))
      .def<Calc>("calc", &GagenKernelResidual::calc, bp::args("self", "data", "x", "u"))
      .def<Calc>("calcDiff", &GagenKernelResidual::calcDiff, bp::args("self", "data", "x", "u"))
      .def("createData", &GagenKernelResidual::createData, bp::with_custodian_and_ward_postcall<0, 2>(),
           bp::args("self", "collector"))
      .add_property("parameter",
                    bp::make_function(&GagenKernelResidual::get_parameter,
                                      bp::return_value_policy<bp::copy_const_reference>()),
                    &GagenKernelResidual::set_parameter, "the kernel's parameter (V_Sd): set it to move the target");
  bp::implicitly_convertible<std::shared_ptr<GagenKernelResidual>,
                             std::shared_ptr<crocoddyl::ResidualModelAbstract>>();
}
