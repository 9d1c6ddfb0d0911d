// The thesis' chapter 5 measurements beside ours: Table 5.1 (the cost of
// the virtual particles) and Fig. 5.15 (a coarse cloth with virtual
// particles against fine cloths without), docs/notes/collisions.md.
#ifndef CLOTHBENCH_HARNESS_VIRTUAL_TABLES_H_
#define CLOTHBENCH_HARNESS_VIRTUAL_TABLES_H_

#include <string>

namespace clothbench {

/// Table 5.1: the three examples (scenes virtual_round_table,
/// virtual_square_table, virtual_ball) with implicit Euler and Newton's
/// method at their h over their 1 s, a frame every step (the refined mesh
/// of every step, as the thesis displayed it). Prints per step the
/// projection, topology (springs and triangulation) and combined time
/// beside the thesis' (R10000, 180 MHz), and the base step's time (the
/// solver's without the virtual particles) with the combined cost
/// relative to it; writes `out` (default out/table_5_1.h5).
/// @return the exit status
int RunTable51(std::string out);

/// Fig. 5.15 as a measurement on the square table at t_end: the 400
/// particles with and without virtual particles, 2,500 and 10,000
/// particles without (the scene refined by RefineGrid), all SBDF(2) at the
/// scene's h. For each: the Hausdorff and rms distances between its
/// surface (the refined mesh with virtual particles) and the 2,500 and
/// 10,000 drapes' (both ways, sampled on a barycentric grid of each
/// triangle), the deepest point of its faces inside the table, and its
/// solver time. Writes `out` (default out/fig_5_15.h5).
/// @return the exit status
int RunFig515(std::string out);

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_VIRTUAL_TABLES_H_
