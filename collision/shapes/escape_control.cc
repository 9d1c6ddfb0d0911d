// EscapeControl (escape_control.h).
#include "collision/shapes/escape_control.h"

#include <fmt/format.h>

namespace clothbench {

std::string EscapeControl(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (std::size_t k = 0; k < text.size(); ++k) {
    const char c = text[k];
    const auto u = static_cast<unsigned char>(c);
    const auto next = [&](std::size_t j) { return k + j < text.size() ? static_cast<unsigned char>(text[k + j]) : 0; };
    if (c == '\n') out += "\\n";
    else if (c == '\t') out += "\\t";
    else if (c == '\r') out += "\\r";
    else if (u < 0x20 || u == 0x7f) out += fmt::format("\\x{:02x}", u);
    // UTF-8 C1 controls U+0080…U+009F (NEL U+0085 among them) and the line
    // and paragraph separators U+2028, U+2029: terminals and log readers
    // break lines at them.
    else if (u == 0xc2 && next(1) >= 0x80 && next(1) <= 0x9f) out += fmt::format("\\u{:04x}", next(1)), ++k;
    else if (u == 0xe2 && next(1) == 0x80 && (next(2) == 0xa8 || next(2) == 0xa9))
      out += fmt::format("\\u{:04x}", 0x2000 + next(2) - 0x80), k += 2;
    else out += c;
  }
  return out;
}

}  // namespace clothbench
