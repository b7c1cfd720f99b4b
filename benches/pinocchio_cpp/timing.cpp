// Pinocchio's crba, rnea and aba timed in C++, with no binding in between: the kernel anchor for
// ribbon's `dynamics` criterion bench. Built and run by benches/pinocchio_cpp.py (see its header);
// the state is the bench's: q_i = 0.3 + 0.1 i, v_i = 0.5 - 0.2 i, a_i = -0.4 + 0.15 i,
// tau_i = 1.0 - 0.3 i.
//
// Usage: timing URDF [CALLS_PER_RUN] [RUNS] [KERNEL]
// Prints one JSON object: nq, nv, and per kernel the minimum over RUNS of the mean time of
// CALLS_PER_RUN calls, in microseconds. With KERNEL (crba_world, crba_local, crba_local_full,
// rnea, aba_world, aba_local) only that kernel runs and the others are reported as -1 (for
// instruction counts).
//
// Pinocchio's crba fills the upper triangle of data.M only (its crba.hpp); crba_local_full adds
// the copy into the strictly lower triangle that its documentation gives, so that it returns the
// whole matrix, as ribbon's crba does.

#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/parsers/urdf.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <string>

namespace {

Eigen::VectorXd ramp(Eigen::Index n, double offset, double step) {
  Eigen::VectorXd out(n);
  for (Eigen::Index i = 0; i < n; ++i) out[i] = offset + step * static_cast<double>(i);
  return out;
}

// Keeps the optimiser from dropping a call whose result is otherwise unused.
template <typename T>
void keep(const T &value) {
  asm volatile("" : : "g"(&value) : "memory");
}

template <typename Kernel>
double best_mean_us(const char *name, const char *only, Kernel kernel, long calls, int runs) {
  if (only != nullptr && std::string(only) != name) return -1.0;
  double best = std::numeric_limits<double>::infinity();
  for (int run = 0; run < runs; ++run) {
    const auto start = std::chrono::steady_clock::now();
    for (long i = 0; i < calls; ++i) kernel();
    const auto stop = std::chrono::steady_clock::now();
    const double us = std::chrono::duration<double, std::micro>(stop - start).count();
    best = std::min(best, us / static_cast<double>(calls));
  }
  return best;
}

}  // namespace

int main(int argc, char **argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s URDF [CALLS_PER_RUN] [RUNS]\n", argv[0]);
    return 2;
  }
  const long calls = argc > 2 ? std::atol(argv[2]) : 200000;
  const int runs = argc > 3 ? std::atoi(argv[3]) : 7;
  const char *only = argc > 4 ? argv[4] : nullptr;
  pinocchio::Model model;
  pinocchio::urdf::buildModel(std::string(argv[1]), model);
  pinocchio::Data data(model);
  const Eigen::VectorXd q = ramp(model.nq, 0.3, 0.1);
  const Eigen::VectorXd v = ramp(model.nv, 0.5, -0.2);
  const Eigen::VectorXd a = ramp(model.nv, -0.4, 0.15);
  const Eigen::VectorXd tau = ramp(model.nv, 1.0, -0.3);

  const double crba_us = best_mean_us(
      "crba_world", only,
      [&] {
        pinocchio::crba(model, data, q, pinocchio::Convention::WORLD);
        keep(data.M);
      },
      calls, runs);
  const double crba_local_us = best_mean_us(
      "crba_local", only,
      [&] {
        pinocchio::crba(model, data, q, pinocchio::Convention::LOCAL);
        keep(data.M);
      },
      calls, runs);
  const double crba_local_full_us = best_mean_us(
      "crba_local_full", only,
      [&] {
        pinocchio::crba(model, data, q, pinocchio::Convention::LOCAL);
        data.M.triangularView<Eigen::StrictlyLower>() =
            data.M.transpose().triangularView<Eigen::StrictlyLower>();
        keep(data.M);
      },
      calls, runs);
  const double rnea_us = best_mean_us(
      "rnea", only,
      [&] {
        pinocchio::rnea(model, data, q, v, a);
        keep(data.tau);
      },
      calls, runs);
  const double aba_us = best_mean_us(
      "aba_world", only,
      [&] {
        pinocchio::aba(model, data, q, v, tau, pinocchio::Convention::WORLD);
        keep(data.ddq);
      },
      calls, runs);
  const double aba_local_us = best_mean_us(
      "aba_local", only,
      [&] {
        pinocchio::aba(model, data, q, v, tau, pinocchio::Convention::LOCAL);
        keep(data.ddq);
      },
      calls, runs);
  std::printf(
      "{\"nq\": %d, \"nv\": %d, \"calls_per_run\": %ld, \"runs\": %d, \"us\": {\"crba_world\": %.5f, "
      "\"crba_local\": %.5f, \"crba_local_full\": %.5f, \"rnea\": %.5f, \"aba_world\": %.5f, "
      "\"aba_local\": %.5f}}\n",
      model.nq, model.nv, calls, runs, crba_us, crba_local_us, crba_local_full_us, rnea_us, aba_us,
      aba_local_us);
  return 0;
}
