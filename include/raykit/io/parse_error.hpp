// raykit/io/parse_error.hpp — the exception every raykit loader throws.
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>

namespace raykit {

/// Thrown on malformed or unreadable input. what() is "FILE:LINE: message", or "FILE: message"
/// when the problem is not tied to a line (e.g. an unreadable file; then line() is 0).
class ParseError : public std::runtime_error {
public:
    ParseError(std::string file, std::size_t line, const std::string& message)
        : std::runtime_error(file + (line ? ":" + std::to_string(line) : std::string()) + ": " + message),
          file_(std::move(file)),
          line_(line) {}
    const std::string& file() const noexcept { return file_; }
    std::size_t line() const noexcept { return line_; }

private:
    std::string file_;
    std::size_t line_;
};

}  // namespace raykit
