// The coupled single-state check of openup_ompl.state_check, compiled: arm joints ->
// forward kinematics -> the palm's normalised distance d to the grasp -> the hand law ->
// the hand joints' placements -> Coal's broadphase query. Optional: built on the user's
// machine by `openup-ompl build-native` (openup_ompl/native/_build.py) against the pin and
// coal wheels' headers and libraries, loaded by openup_ompl.native (boost.python, so that
// the Python objects pin.Data and the broadphase manager are used in place, without copies).
#include <boost/python.hpp>
#include <boost/version.hpp>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <coal/broadphase/broadphase_bruteforce.h>
#include <coal/config.hh>

#include "pinocchio/algorithm/frames.hpp"
#include "pinocchio/algorithm/geometry.hpp"
#include "pinocchio/algorithm/kinematics.hpp"
#include "pinocchio/collision/broadphase.hpp"
#include "pinocchio/multibody.hpp"
#include "pinocchio/spatial.hpp"

namespace bp = boost::python;
using Model = pinocchio::Model;
using Data = pinocchio::Data;
using Manager = pinocchio::BroadPhaseManagerTpl<coal::NaiveCollisionManager>;
using Vector = Eigen::VectorXd;
using Step = pinocchio::impl::ForwardKinematicZeroStep<double, 0, pinocchio::JointCollectionDefaultTpl, Vector>;

namespace {

std::vector<double> doubles(const bp::object& sequence) {
  std::vector<double> out;
  const long n = bp::len(sequence);
  out.reserve(n);
  for (long k = 0; k < n; ++k) out.push_back(bp::extract<double>(sequence[k]));
  return out;
}

std::vector<long> indices(const bp::object& sequence) {
  std::vector<long> out;
  const long n = bp::len(sequence);
  for (long k = 0; k < n; ++k) out.push_back(bp::extract<long>(sequence[k]));
  return out;
}

// a * a exactly, as hi + lo (Veltkamp's split; no overflow for lengths in metres).
inline void exact_square(double a, double& hi, double& lo) {
  const double c = 134217729.0 * a;  // 2**27 + 1
  const double high = c - (c - a);
  const double low = a - high;
  hi = a * a;
  lo = ((high * high - hi) + 2.0 * high * low) + low * low;
}

// a + b exactly, as hi + lo (Knuth's two-sum).
inline void exact_sum(double a, double b, double& hi, double& lo) {
  hi = a + b;
  const double bb = hi - a;
  lo = (a - (hi - bb)) + (b - bb);
}

// The Euclidean norm correctly rounded but for rare near-ties, as CPython's math.dist
// gives it (StateChecker's translation distance): the sum of squares in double-double,
// its square root corrected by one Newton step.
inline double rounded_norm(const Eigen::Vector3d& v) {
  double sum, err, hi, lo, carry;
  exact_square(v[0], sum, err);
  for (int k = 1; k < 3; ++k) {
    exact_square(v[k], hi, lo);
    exact_sum(sum, hi, sum, carry);
    err += carry + lo;
  }
  double total, total_lo;
  exact_sum(sum, err, total, total_lo);
  if (total <= 0.0) return 0.0;
  double h = std::sqrt(total);
  exact_square(h, hi, lo);
  const double residual = ((total - hi) - lo) + total_lo;
  return h + residual / (2.0 * h);
}

// The law and the distance, as StateChecker holds them (see its __init__ and HandLaw).
class CoupledCheck {
 public:
  // law: a dict with mga, arrival, low_slope, high, clip_low, lower, upper, fixed (a list or
  // None), goal (3), goal_rotation_t (9, row-major, or None for the translation distance),
  // rotation_weight, inv_start.
  CoupledCheck(bp::object data, bp::object manager, bp::object arm_q, bp::object hand_q,
               long palm_frame, bp::object q, bp::dict law)
      : data_obj_(data), manager_obj_(manager),
        data_(bp::extract<Data&>(data)), manager_(bp::extract<Manager&>(manager)),
        model_(manager_.getModel()), palm_(palm_frame),
        arm_(indices(arm_q)), hand_(indices(hand_q)) {
    const std::vector<double> q0 = doubles(q);
    if (static_cast<long>(q0.size()) != model_.nq) throw std::invalid_argument("q: nq values");
    if (!model_.check(data_)) throw std::invalid_argument("data: not the manager model's");
    for (const std::vector<long>* selector : {&arm_, &hand_})
      for (long i : *selector)
        if (i < 0 || i >= model_.nq) throw std::invalid_argument("arm_q, hand_q: indices in q");
    q_ = Eigen::Map<const Vector>(q0.data(), q0.size());
    full_ = q_;
    mga_ = bp::extract<double>(law["mga"]);
    arrival_ = doubles(law["arrival"]);
    slope_ = doubles(law["low_slope"]);
    high_ = doubles(law["high"]);
    lower_ = doubles(law["lower"]);
    upper_ = doubles(law["upper"]);
    clip_low_ = bp::extract<bool>(law["clip_low"]);
    const std::vector<double> goal = doubles(law["goal"]);
    if (goal.size() != 3) throw std::invalid_argument("goal: 3 coordinates");
    goal_ = Eigen::Map<const Eigen::Vector3d>(goal.data());
    inv_start_ = bp::extract<double>(law["inv_start"]);
    rotation_weight_ = bp::extract<double>(law["rotation_weight"]);
    weighted_ = !bp::object(law["goal_rotation_t"]).is_none();
    if (weighted_) {
      const std::vector<double> r = doubles(law["goal_rotation_t"]);
      if (r.size() != 9) throw std::invalid_argument("goal_rotation_t: 9 values");
      goal_rotation_t_ = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(r.data());
    }
    fixed_ = !bp::object(law["fixed"]).is_none();
    const size_t nh = hand_.size();
    if (arrival_.size() != nh || slope_.size() != nh || high_.size() != nh ||
        lower_.size() != nh || upper_.size() != nh)
      throw std::invalid_argument("law: one value per hand joint");
    if (fixed_) {
      const std::vector<double> f = doubles(law["fixed"]);
      if (f.size() != nh) throw std::invalid_argument("fixed: one value per hand joint");
      for (size_t k = 0; k < nh; ++k) q_[hand_[k]] = f[k];
    }
    // The joints the hand moves: those with a hand coordinate, and their descendants.
    std::vector<bool> is_hand_q(model_.nq, false);
    for (long i : hand_) is_hand_q.at(i) = true;
    std::vector<bool> moved(model_.njoints, false);
    for (pinocchio::JointIndex j = 1; j < static_cast<pinocchio::JointIndex>(model_.njoints); ++j) {
      const auto& joint = model_.joints[j];
      bool own = false;
      for (int k = 0; k < joint.nq(); ++k) own = own || is_hand_q[joint.idx_q() + k];
      moved[j] = own || moved[model_.parents[j]];
      (moved[j] ? hand_joints_ : arm_joints_).push_back(j);
    }
    if (palm_ < 0 || palm_ >= static_cast<long>(model_.nframes))
      throw std::invalid_argument("palm_frame: a frame index");
    if (moved[model_.frames[palm_].parentJoint])
      throw std::invalid_argument("palm_frame: moved by a hand joint");
  }

  // Whether the arm state (any sequence of floats), the hand set by the law, is free.
  bool is_valid(bp::object arm) {
    write_arm(arm);
    if (fixed_) {
      distance_ = std::numeric_limits<double>::infinity();
      return !pinocchio::computeCollisions(model_, data_, manager_, q_, true);
    }
    for (auto j : arm_joints_) step(j);
    distance_ = palm_distance();
    set_hand(distance_);
    for (auto j : hand_joints_) step(j);
    pinocchio::updateGeometryPlacements(model_, data_, manager_.getGeometryModel(),
                                        manager_.getGeometryData());
    manager_.update(false);
    pinocchio::CollisionCallBackDefault callback(manager_.getGeometryModel(),
                                                 manager_.getGeometryData(), true);
    return !pinocchio::computeCollisions(manager_, &callback);
  }

  // Whether the full configuration (nq floats) is free: the bare query, as
  // pin.computeCollisions(model, data, manager, q, True) makes it (for comparison).
  bool is_valid_q(bp::object q) {
    read(q, full_, nullptr);
    return !pinocchio::computeCollisions(model_, data_, manager_, full_, true);
  }

  // Collision flags of the columns of a float64 array of shape (nq, n), checked one by
  // one in this thread as CollisionWorld.batch_in_collision's serial path does (stopping
  // at the first collision if asked; the flags after it are then false).
  bp::list collides_columns(bp::object qs, bool stop_at_first) {
    Py_buffer view;
    if (PyObject_GetBuffer(qs.ptr(), &view, PyBUF_STRIDES | PyBUF_FORMAT) != 0)
      bp::throw_error_already_set();
    const bool ok = view.ndim == 2 && view.shape[0] == model_.nq && view.format != nullptr &&
                    std::string(view.format) == "d";
    if (!ok) {
      PyBuffer_Release(&view);
      throw std::invalid_argument("qs: a float64 array of shape (nq, n)");
    }
    const char* base = static_cast<const char*>(view.buf);
    const Py_ssize_t n = view.shape[1];
    std::vector<bool> flags(n, false);
    for (Py_ssize_t c = 0; c < n; ++c) {
      for (Py_ssize_t r = 0; r < view.shape[0]; ++r)
        full_[r] = *reinterpret_cast<const double*>(base + r * view.strides[0] + c * view.strides[1]);
      flags[c] = pinocchio::computeCollisions(model_, data_, manager_, full_, true);
      if (flags[c] && stop_at_first) break;
    }
    PyBuffer_Release(&view);
    bp::list out;
    for (bool flag : flags) out.append(flag);
    return out;
  }

  // d at a full configuration (a float64 array of nq values, any stride): the arm joints'
  // placements and the palm's, as StateChecker._palm_distance computes it (the hand
  // joints move no frame d reads). Leaves distance unchanged.
  double distance_q(bp::object q) {
    Py_buffer view;
    if (PyObject_GetBuffer(q.ptr(), &view, PyBUF_STRIDES | PyBUF_FORMAT) != 0)
      bp::throw_error_already_set();
    const bool ok = view.ndim == 1 && view.shape[0] == model_.nq && view.format != nullptr &&
                    std::string(view.format) == "d";
    if (!ok) {
      PyBuffer_Release(&view);
      throw std::invalid_argument("q: a float64 array of nq values");
    }
    const char* base = static_cast<const char*>(view.buf);
    for (long i : arm_) q_[i] = *reinterpret_cast<const double*>(base + i * view.strides[0]);
    PyBuffer_Release(&view);
    for (auto j : arm_joints_) step(j);
    return palm_distance();
  }

  double distance() const { return distance_; }

 private:
  void write_arm(const bp::object& arm) { read(arm, q_, &arm_); }

  // Write the floats of a Python sequence into out[where[k]] (out[k] without where).
  static void read(const bp::object& values, Vector& out, const std::vector<long>* where) {
    PyObject* seq = PySequence_Fast(values.ptr(), "a sequence of floats");
    if (seq == nullptr) bp::throw_error_already_set();
    const Py_ssize_t n = PySequence_Fast_GET_SIZE(seq);
    if (n != static_cast<Py_ssize_t>(where ? where->size() : out.size())) {
      Py_DECREF(seq);
      throw std::invalid_argument(where ? "arm: one value per arm joint" : "q: nq values");
    }
    PyObject** items = PySequence_Fast_ITEMS(seq);
    for (Py_ssize_t k = 0; k < n; ++k) out[where ? (*where)[k] : k] = PyFloat_AsDouble(items[k]);
    Py_DECREF(seq);
    if (PyErr_Occurred()) bp::throw_error_already_set();
  }

  void step(pinocchio::JointIndex j) {
    Step::run(model_.joints[j], data_.joints[j], Step::ArgsType(model_, data_, q_));
  }

  double palm_distance() {
    const pinocchio::SE3& palm = pinocchio::updateFramePlacement(model_, data_, palm_);
    double d = weighted_ ? (palm.translation() - goal_).norm()
                         : rounded_norm(palm.translation() - goal_);
    if (weighted_) {
      const Eigen::Matrix3d relative = goal_rotation_t_ * palm.rotation();
      d += rotation_weight_ * pinocchio::log3(relative).norm();
    }
    return d * inv_start_;
  }

  void set_hand(double d) {
    const size_t nh = hand_.size();
    if (d > mga_) {
      for (size_t k = 0; k < nh; ++k) q_[hand_[k]] = high_[k];
      return;
    }
    for (size_t k = 0; k < nh; ++k) {
      double value = slope_[k] * d;
      value = value + arrival_[k];
      if (clip_low_) value = std::min(std::max(value, lower_[k]), upper_[k]);
      q_[hand_[k]] = value;
    }
  }

  bp::object data_obj_, manager_obj_;  // keep the Python objects alive
  Data& data_;
  Manager& manager_;
  const Model& model_;
  long palm_;
  std::vector<long> arm_, hand_;
  std::vector<pinocchio::JointIndex> arm_joints_, hand_joints_;
  Vector q_, full_;
  double mga_ = 0, inv_start_ = 1, rotation_weight_ = 0, distance_ = 0;
  std::vector<double> arrival_, slope_, high_, lower_, upper_;
  bool clip_low_ = false, weighted_ = false, fixed_ = false;
  Eigen::Vector3d goal_;
  Eigen::Matrix3d goal_rotation_t_ = Eigen::Matrix3d::Identity();
};

}  // namespace

BOOST_PYTHON_MODULE(_coupled_check) {
  // The versions compiled against: the module uses the Python objects' C++ types in
  // place, so it may only run with these very builds (openup_ompl.native.load checks them).
  bp::dict built_with;
  built_with["pinocchio"] = PINOCCHIO_VERSION;
  built_with["coal"] = COAL_VERSION;
  built_with["boost"] = BOOST_LIB_VERSION;
  bp::scope().attr("built_with") = built_with;
  bp::class_<CoupledCheck, boost::noncopyable>(
      "CoupledCheck",
      "The coupled check of one arm state (forward kinematics once, d, the law's hand, "
      "Coal), on a pin.Data and a naive broadphase manager.",
      bp::init<bp::object, bp::object, bp::object, bp::object, long, bp::object, bp::dict>(
          bp::args("self", "data", "manager", "arm_q", "hand_q", "palm_frame", "q", "law")))
      .def("is_valid", &CoupledCheck::is_valid, bp::args("self", "arm"),
           "Whether the arm state, the hand set by the law (or fixed), is collision-free.")
      .def("is_valid_q", &CoupledCheck::is_valid_q, bp::args("self", "q"),
           "Whether the full configuration (nq floats) is collision-free: the bare query.")
      .def("collides_columns", &CoupledCheck::collides_columns,
           bp::args("self", "qs", "stop_at_first"),
           "Collision flags of the columns of a float64 (nq, n) array, one by one.")
      .def("distance_q", &CoupledCheck::distance_q, bp::args("self", "q"),
           "d at a full configuration (a float64 array of nq values).")
      .add_property("distance", &CoupledCheck::distance,
                    "d at the last state checked (inf for a fixed hand).");
}
