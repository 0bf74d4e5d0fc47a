// The input-error type every reader and the scene parser throw (exit 2 in the command).
#pragma once

#include <stdexcept>
#include <string>

namespace cutsim {

// Bad input (a mesh or scene file): the message names the file and line, or the key.
class InputError : public std::runtime_error {
public:
    InputError(const std::string& file, long line, const std::string& what);
    explicit InputError(const std::string& what);
};

// `s` with control bytes and bytes that are not UTF-8 written as \xNN, so that a message quoting a
// file name or a token of a binary file prints as text.
std::string printableText(const std::string& s);

}  // namespace cutsim
