/// @file format.h
/// printf into a std::string, for the node's report and log lines.
#pragma once

#include <cstdarg>
#include <string>

namespace deformable_flsm {

/// `format` with its arguments, as printf would print them (any length).
std::string formatted(const char* format, ...) __attribute__((format(printf, 1, 2)));
/// The same with a va_list (for a function that takes `...` itself).
std::string vformatted(const char* format, va_list args);

}  // namespace deformable_flsm
