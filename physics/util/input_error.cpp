#include "util/input_error.hpp"

namespace cutsim {

std::string printableText(const std::string& s) {
    std::string out;
    out.reserve(s.size());
    auto hex = [&](unsigned char c) {
        static const char* d = "0123456789abcdef";
        out += "\\x";
        out += d[c >> 4];
        out += d[c & 15];
    };
    for (size_t i = 0; i < s.size();) {
        const auto c = static_cast<unsigned char>(s[i]);
        if (c < 0x80) {
            if (c < 0x20 || c == 0x7f)
                hex(c);
            else
                out += static_cast<char>(c);
            ++i;
            continue;
        }
        // a well-formed UTF-8 sequence (no overlongs or surrogates checked beyond the lead byte)
        const int n = (c & 0xE0) == 0xC0 && c >= 0xC2   ? 2
                      : (c & 0xF0) == 0xE0              ? 3
                      : (c & 0xF8) == 0xF0 && c <= 0xF4 ? 4
                                                        : 0;
        bool ok = n > 0 && i + n <= s.size();
        for (int k = 1; ok && k < n; ++k) ok = (static_cast<unsigned char>(s[i + k]) & 0xC0) == 0x80;
        if (ok) {
            out.append(s, i, n);
            i += n;
        } else {
            hex(c);
            ++i;
        }
    }
    return out;
}

InputError::InputError(const std::string& file, long line, const std::string& what)
    : std::runtime_error(
          printableText(line > 0 ? file + ":" + std::to_string(line) + ": " + what : file + ": " + what)) {}

InputError::InputError(const std::string& what) : std::runtime_error(printableText(what)) {}

}  // namespace cutsim
