// The registry of methods: one line per method, naming the function that
// defines its row beside its code (MethodEntry, solver/method_row.h). The
// order of the lines is the tables' order. A new method is its files and
// one line here (docs/guide/extending.md, "Adding a method").
#include <algorithm>
#include <stdexcept>
#include <string>
#include <utility>

#include "harness/methods.h"

// X(row): one line per method.
#define CLOTHBENCH_METHODS(X) \
  X(ImexEulerRow)             \
  X(ImplicitEulerRow)         \
  X(Sbdf2Row)                 \
  X(Bdf2Row)                  \
  X(ImplicitMidpointRow)      \
  X(Sbdf3Row)                 \
  X(SymplecticEulerRow)       \
  X(BaraffWitkinRow)          \
  X(BlenderRow)               \
  X(XpbdRow)                  \
  X(ProjectiveDynamicsRow)    \
  X(VbdRow)                   \
  X(ArkodeRow)                \
  X(CvodeRow)                 \
  X(IdaRow)

namespace clothbench {

#define CLOTHBENCH_DECLARE_METHOD(row) MethodEntry row();
CLOTHBENCH_METHODS(CLOTHBENCH_DECLARE_METHOD)
#undef CLOTHBENCH_DECLARE_METHOD

namespace {

// The one entry whose `flag` is set. @throws std::logic_error if not exactly one is.
const MethodEntry& TheOne(bool MethodEntry::*flag, const char* what) {
  const MethodEntry* found = nullptr;
  for (const MethodEntry& e : Registry())
    if (e.*flag) {
      if (found) throw std::logic_error(std::string("two methods are the ") + what);
      found = &e;
    }
  if (!found) throw std::logic_error(std::string("no method is the ") + what);
  return *found;
}

}  // namespace

const std::vector<MethodEntry>& Registry() {
#define CLOTHBENCH_METHOD_ENTRY(row) row(),
  static const std::vector<MethodEntry> rows = {CLOTHBENCH_METHODS(CLOTHBENCH_METHOD_ENTRY)};
#undef CLOTHBENCH_METHOD_ENTRY
  return rows;
}

const std::vector<DefaultRow>& DefaultRows() {
  static const std::vector<DefaultRow> rows = [] {
    std::vector<DefaultRow> fixed, adaptive;
    for (const MethodEntry& e : Registry())
      for (const RowDefaults& d : e.defaults) {
        DefaultRow row{std::string(e.name) + (d.modifiers.empty() ? "" : "/") + std::string(d.modifiers),
                       {d.h_factors, d.rtols, d.iterations}, d.newton_variant};
        (SpecOf(e.kind).adaptive() || d.error_row() ? adaptive : fixed).push_back(std::move(row));
      }
    fixed.insert(fixed.end(), adaptive.begin(), adaptive.end());
    return fixed;
  }();
  return rows;
}

std::string_view DefaultReference() { return TheOne(&MethodEntry::default_reference, "default reference").name; }

const MethodEntry& KernelBenchmarkMethod() {
  return TheOne(&MethodEntry::kernel_benchmark, "kernel benchmark");
}

const MethodEntry& SelfConvergenceMethod() {
  return TheOne(&MethodEntry::self_convergence_reference, "self-convergence reference");
}

const MethodEntry& ThesisExperimentMethod(std::string_view experiment) {
  const MethodEntry* found = nullptr;
  for (const MethodEntry& e : Registry())
    if (std::find(e.thesis_experiments.begin(), e.thesis_experiments.end(), experiment) != e.thesis_experiments.end()) {
      if (found) throw std::logic_error(std::string("two methods ran ") + std::string(experiment));
      found = &e;
    }
  if (!found) throw std::logic_error(std::string("no method ran ") + std::string(experiment));
  return *found;
}

}  // namespace clothbench
