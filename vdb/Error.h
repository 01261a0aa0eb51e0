// Errors in layers (see ../STYLE): programming errors are asserts; bad input
// (a file, a path, a parameter) throws InputError with a one-line message that
// names the culprit and what is wrong; long work cancelled through an
// Interrupter throws Cancelled. Tools catch both in main() and exit non-zero.
#pragma once

#include <stdexcept>
#include <string>

namespace mtcut {

/// Bad input a user can act on. what() is one line, e.g.
/// "head/IM37.dcm: slice has 511 columns, expected 512".
class InputError : public std::runtime_error
{
public:
    using std::runtime_error::runtime_error;
};

/// Long work stopped because an Interrupter asked for it.
class Cancelled : public std::runtime_error
{
public:
    Cancelled() : std::runtime_error("cancelled") {}
};

} // namespace mtcut
