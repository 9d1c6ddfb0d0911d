// Notes that more than one scheme's row prints (MethodEntry::status_notes).
#ifndef CLOTHBENCH_SOLVER_SCHEMES_NOTES_H_
#define CLOTHBENCH_SOLVER_SCHEMES_NOTES_H_

#include <string_view>

namespace clothbench {

// Why SBDF(2) and BDF(2) end `penetration` at a large h with the history
// kept (docs/notes/collisions.md, "BDF(2) at the obstacles").
inline constexpr std::string_view kMultistepPenetration =
    "sbdf2/bdf2 rows, penetration: with contact_history = \"keep\" (the default) the multistep formula x1 = (4 x0 - "
    "x-1)/3 + 2h v1/3 carries the last step's displacement on, so in the step after an entry a particle moves about "
    "h|<v0, D>|/3 toward the obstacle whatever v1 the response sets, and it can end deeper than the collision "
    "distance delta once h > 6 delta/|<v0, D>|. A property of the method with this response; contact_history = "
    "\"project\" or \"land\" removes it (docs/notes/collisions.md, \"BDF(2) at the obstacles\").";

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_SCHEMES_NOTES_H_
