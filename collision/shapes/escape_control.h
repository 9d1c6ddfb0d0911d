// One-line messages from any text: EscapeControl, shared by every layer that
// names a file's contents or a user's string in an error (the lowest one
// that needs it is the mesh reader's header check).
#ifndef CLOTHBENCH_COLLISION_SHAPES_ESCAPE_CONTROL_H_
#define CLOTHBENCH_COLLISION_SHAPES_ESCAPE_CONTROL_H_

#include <string>
#include <string_view>

namespace clothbench {

/// `text` for a one-line message: control characters (and DEL) become
/// escapes (\n, \t, \r, \xNN), the UTF-8 C1 controls and the line and
/// paragraph separators U+2028 and U+2029 become \uNNNN; printable text and
/// other UTF-8 are kept.
std::string EscapeControl(std::string_view text);

}  // namespace clothbench

#endif  // CLOTHBENCH_COLLISION_SHAPES_ESCAPE_CONTROL_H_
