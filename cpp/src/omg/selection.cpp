#include "pickplan/omg/selection.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <stdexcept>
#include <string>

namespace pickplan::omg {

namespace {

// numpy's pairwise summation (loops_utils.h: 8 partial sums up to 128 entries, halves beyond).
double pairwise(const double* a, long n) {
  if (n < 8) {
    double res = 0.0;
    for (long i = 0; i < n; ++i) res += a[i];
    return res;
  }
  if (n <= 128) {
    double r[8];
    for (int j = 0; j < 8; ++j) r[j] = a[j];
    long i = 8;
    for (; i < n - (n % 8); i += 8)
      for (int j = 0; j < 8; ++j) r[j] += a[i + j];
    double res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]));
    for (; i < n; ++i) res += a[i];
    return res;
  }
  long n2 = n / 2;
  n2 -= n2 % 8;
  return pairwise(a, n2) + pairwise(a + n2, n - n2);
}

Eigen::VectorXd one_hot(long n, long i) {
  Eigen::VectorXd p = Eigen::VectorXd::Zero(n);
  p[i] = 1.0;
  return p;
}

long argmin(const Eigen::VectorXd& c) {  // first minimum, as np.argmin
  long best = 0;
  for (long i = 1; i < c.size(); ++i)
    if (c[i] < c[best]) best = i;
  return best;
}

long argmax(const double* p, long n) {  // first maximum, as np.argmax
  long best = 0;
  for (long i = 1; i < n; ++i)
    if (p[i] > p[best]) best = i;
  return best;
}

// p ∝ p exp(-eta c) in log space (selection.py's _multiplicative).
Eigen::VectorXd multiplicative(const Eigen::VectorXd& p, const Eigen::VectorXd& c, double eta) {
  Eigen::VectorXd logits(p.size());
  for (long i = 0; i < p.size(); ++i) logits[i] = std::log(std::max(p[i], 1e-300)) - eta * c[i];
  const double top = logits.maxCoeff();
  for (long i = 0; i < p.size(); ++i) logits[i] = std::exp(logits[i] - top);
  const double sum = numpy_sum(logits.data(), logits.size());
  return logits / sum;
}

}  // namespace

double numpy_sum(const double* a, long n) { return 0.0 + pairwise(a, n); }

Eigen::MatrixXd shifted_kl_step(const Eigen::MatrixXd& P, const Eigen::MatrixXd& S, double shift) {
  if (S.rows() != P.rows() || S.cols() != P.cols())
    throw std::invalid_argument("shifted KL step: costs and distributions differ in shape");
  const long K = P.rows(), G = P.cols();
  Eigen::MatrixXd out(K, G);
  std::vector<double> a(G), sorted(G), scale(G), row(G);
  for (long r = 0; r < K; ++r) {
    for (long j = 0; j < G; ++j) a[j] = std::log(std::max(P(r, j) + shift, 1e-300)) - S(r, j);
    const double top = *std::max_element(a.begin(), a.end());
    for (long j = 0; j < G; ++j) a[j] = std::exp(a[j] - top);
    if (shift == 0.0) {
      const double sum = numpy_sum(a.data(), G);
      for (long j = 0; j < G; ++j) out(r, j) = a[j] / sum;
      continue;
    }
    sorted = a;
    std::sort(sorted.begin(), sorted.end(), std::greater<double>());
    double cum = 0.0;
    long kstar = G - 1;  // np.argmax of an all-false reversed mask gives the last index
    bool found = false;
    for (long j = 0; j < G; ++j) {
      cum += sorted[j];
      scale[j] = (1.0 + static_cast<double>(j + 1) * shift) / cum;
    }
    for (long j = G - 1; j >= 0 && !found; --j)
      if (sorted[j] * scale[j] > shift) kstar = j, found = true;
    const double e_lam = scale[kstar];
    for (long j = 0; j < G; ++j) row[j] = std::max(a[j] * e_lam - shift, 0.0);
    const double sum = numpy_sum(row.data(), G);
    for (long j = 0; j < G; ++j) out(r, j) = row[j] / sum;
  }
  return out;
}

SelectionPolicy::SelectionPolicy(SelectionSettings settings) : settings_(std::move(settings)) {
  if (settings_.kind == SelectionKind::MD && settings_.md_exponents.empty())
    throw std::invalid_argument("selection: mirror descent needs at least one learning-rate exponent");
}

void SelectionPolicy::require_reset() const {
  if (p_.size() == 0) throw std::logic_error("selection policy used before reset()");
}

void SelectionPolicy::reset(int num_goals, int horizon, const Eigen::VectorXd* initial_costs) {
  if (num_goals < 1) throw std::invalid_argument("a selection policy needs at least one goal");
  horizon_ = std::max(1, horizon);
  p_ = Eigen::VectorXd::Constant(num_goals, 1.0 / num_goals);
  costs_.clear();
  played_.clear();
  if (settings_.kind == SelectionKind::MD) {
    const long K = static_cast<long>(settings_.md_exponents.size());
    experts_ = p_.transpose().replicate(K, 1);
    weights_ = Eigen::VectorXd::Constant(K, 1.0 / K);
  }
  if (initial_costs && settings_.kind == SelectionKind::Fixed) {
    if (initial_costs->size() != num_goals)
      throw std::invalid_argument("initial costs: expected " + std::to_string(num_goals) + " entries, got " +
                                  std::to_string(initial_costs->size()));
    p_ = one_hot(num_goals, argmin(*initial_costs));
  }
}

void SelectionPolicy::add_goal() {
  require_reset();
  const long n = p_.size();
  const double extra = p_.maxCoeff();
  Eigen::VectorXd grown(n + 1);
  grown << p_, extra;
  p_ = grown / (1.0 + extra);
  for (Eigen::VectorXd& c : costs_) {
    const double low = c.minCoeff();
    c.conservativeResize(n + 1);
    c[n] = low;
  }
  for (Eigen::VectorXd& q : played_) {
    q.conservativeResize(n + 1);
    q[n] = 0.0;
  }
  if (settings_.kind == SelectionKind::Fixed) {
    p_ = one_hot(n + 1, argmax(p_.data(), n));
  } else if (settings_.kind == SelectionKind::MD) {
    const Eigen::VectorXd top = experts_.rowwise().maxCoeff();
    experts_.conservativeResize(Eigen::NoChange, n + 1);
    experts_.col(n) = top;
    for (long r = 0; r < experts_.rows(); ++r) experts_.row(r) /= 1.0 + top[r];
  }
}

const Eigen::VectorXd& SelectionPolicy::update(const Eigen::VectorXd& c) {
  require_reset();
  if (c.size() != p_.size())
    throw std::invalid_argument("costs: expected " + std::to_string(p_.size()) + " entries, got " +
                                std::to_string(c.size()));
  if (!c.allFinite()) throw std::invalid_argument("costs must be finite");
  played_.push_back(p_);
  costs_.push_back(c);
  p_ = next(c);
  return p_;
}

Eigen::VectorXd SelectionPolicy::next(const Eigen::VectorXd& c) {
  const long n = c.size();
  switch (settings_.kind) {
    case SelectionKind::Fixed:
      return p_;
    case SelectionKind::FTC:
    case SelectionKind::Proj:
      return one_hot(n, argmin(c));
    case SelectionKind::FTL: {
      Eigen::VectorXd total = costs_.front();  // row by row, as numpy's sum over axis 0
      for (size_t i = 1; i < costs_.size(); ++i) total += costs_[i];
      return one_hot(n, argmin(total));
    }
    case SelectionKind::EXP: {
      const double eta = settings_.exp_eta > 0
                             ? settings_.exp_eta
                             : std::sqrt(std::max(std::log(static_cast<double>(n)), 1e-12) / horizon_);
      return multiplicative(p_, c, eta);
    }
    case SelectionKind::MD:
      return md_next(c);
  }
  throw std::logic_error("unknown selection policy");
}

Eigen::VectorXd SelectionPolicy::md_next(const Eigen::VectorXd& c) {
  const long K = experts_.rows(), G = experts_.cols();
  const double log_n = std::log(static_cast<double>(std::max(horizon_, 2)));
  Eigen::MatrixXd scaled(K, G);
  for (long k = 0; k < K; ++k) {
    const double eta = std::pow(2.0, settings_.md_exponents[k]) * log_n;
    for (long j = 0; j < G; ++j) scaled(k, j) = eta * c[j];
  }
  const double shift = settings_.md_shift >= 0 ? settings_.md_shift : 1.0 / (4.0 * G + 1.0);
  Eigen::MatrixXd fresh = shifted_kl_step(experts_, scaled, shift);
  Eigen::VectorXd losses(K);
  std::vector<double> moved(G);
  for (long k = 0; k < K; ++k) {
    double dot = 0.0;
    for (long j = 0; j < G; ++j) dot += fresh(k, j) * c[j];
    for (long j = 0; j < G; ++j) moved[j] = std::abs(fresh(k, j) - experts_(k, j));
    losses[k] = dot + numpy_sum(moved.data(), G);
  }
  const double meta_eta = K > 1 ? std::sqrt(std::log(static_cast<double>(K)) / horizon_) : 0.0;
  weights_ = multiplicative(weights_, losses, meta_eta);
  experts_ = std::move(fresh);
  Eigen::VectorXd p = Eigen::VectorXd::Zero(G);
  for (long k = 0; k < K; ++k) p += weights_[k] * experts_.row(k).transpose();
  return p / numpy_sum(p.data(), G);
}

int SelectionPolicy::select() const {
  require_reset();
  return static_cast<int>(argmax(p_.data(), p_.size()));
}

double SelectionPolicy::regret() const {
  if (costs_.empty()) return 0.0;
  double played = 0.0;
  Eigen::VectorXd total = Eigen::VectorXd::Zero(p_.size());
  for (size_t i = 0; i < costs_.size(); ++i) {
    played += costs_[i].dot(played_[i]);
    total += costs_[i];
  }
  return played - total.minCoeff();
}

}  // namespace pickplan::omg
