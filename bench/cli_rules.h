// Command-line rules every executable shares beyond CLI11's own parsing.
#ifndef CLOTHBENCH_BENCH_CLI_RULES_H_
#define CLOTHBENCH_BENCH_CLI_RULES_H_

#include <string>

#include <CLI/CLI.hpp>

namespace clothbench {

/// Refuses an option given an empty value (`--h ''`, `--table ''`, or an
/// empty item of a list such as `--at 0.01,,0.02`), in `app` and its
/// subcommands: an empty value would otherwise run the option's default
/// silently. Flags (options without a value) are not checked.
/// @throws CLI::ValidationError "<option>: an empty value is not a <what>"
///   (exit 2, as CLI11's own refusals)
inline void RefuseEmptyValues(const CLI::App& app) {
  for (const CLI::Option* o : app.get_options()) {
    if (o->get_type_size() == 0 || o->count() == 0) continue;  // a flag, or not given
    for (const std::string& v : o->results())
      if (v.empty())
        throw CLI::ValidationError(o->get_name(), "an empty value (or an empty item of a list) is not allowed");
  }
  for (const CLI::App* sub : app.get_subcommands()) RefuseEmptyValues(*sub);
}

}  // namespace clothbench

#endif  // CLOTHBENCH_BENCH_CLI_RULES_H_
