// raykit/io/parse_error.hpp — the exception every raykit loader throws.
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>

namespace raykit {

/// Thrown on malformed or unreadable input. what() is "FILE:LINE: message"
/// (LINE is 0 when the problem is not tied to a line, e.g. an unreadable file).
class ParseError : public std::runtime_error {
public:
    ParseError(std::string file, std::size_t line, const std::string& message)
        : std::runtime_error(file + ":" + std::to_string(line) + ": " + message),
          file_(std::move(file)),
          line_(line) {}
    const std::string& file() const noexcept { return file_; }
    std::size_t line() const noexcept { return line_; }

private:
    std::string file_;
    std::size_t line_;
};

}  // namespace raykit
