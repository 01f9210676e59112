// examples/cli_common.hpp — what every `raykit` command shares: the one usage-error type, the
// CLI11 validators for raykit's bounded numbers, the help formatter and a parse helper.
//
// The command line is parsed by CLI11 (Debian libcli11-dev; header-only), for the CLI only:
// the raykit library (include/) never sees it.
//
//   raykit_cli::UsageError            bad usage of any command (exit code 2, after a short usage
//                                     line); everything else is another std::exception (exit 1)
//   raykit_cli::count_in(lo, hi)      CLI11 transform: an integer in [lo, hi] ("+N" and integral
//                                     exponent forms such as 1e6 too; a negative or huge value is
//                                     out of range, never wrapped), rewritten as plain digits
//   raykit_cli::finite()              CLI11 check: a finite number (every value of the option)
//   raykit_cli::real_in(pred, why)    CLI11 check: a finite number for which pred holds
//   raykit_cli::parse_args(app, argc, argv, first)
//                                     parses argv[first ..] with `app` (its options added);
//                                     a CLI11 parse error becomes a UsageError
//   raykit_cli::Formatter             CLI11's help layout, multi-value options shown by their
//                                     value names ("--camera EX EY EZ TX TY TZ"), sets as sets,
//                                     deprecated names (group Formatter::kDeprecated) left out
#pragma once

#include <CLI/CLI.hpp>

#include <charconv>
#include <cmath>
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

namespace raykit_cli {

/// Bad command-line usage of any raykit command: exit code 2.
struct UsageError : std::invalid_argument {
    using std::invalid_argument::invalid_argument;
};

/// Why `s` is not an integer in [lo, hi] ("" when it is; `out` gets it). Accepts "+N" and
/// integral exponent forms ("1e6"); a negative or huge value is out of range, never wrapped.
inline std::string count_problem(std::string_view v, std::uint64_t lo, std::uint64_t hi, std::uint64_t& out) {
    const std::string s(v);
    const std::string range = "must be in " + std::to_string(lo) + ".." + std::to_string(hi) + ", got '" + s + "'";
    if (!v.empty() && v[0] == '+') v.remove_prefix(1);
    std::uint64_t u = 0;
    const auto [p, ec] = std::from_chars(v.data(), v.data() + v.size(), u);
    if (!v.empty() && p == v.data() + v.size() && ec == std::errc()) {
        out = u;
        return u < lo || u > hi ? range : "";
    }
    if (!v.empty() && p == v.data() + v.size() && ec == std::errc::result_out_of_range) return range;
    double d = 0.0;  // "-3", "1e12", "2.5", "inf"
    const auto [q, ed] = std::from_chars(v.data(), v.data() + v.size(), d);
    if (v.empty() || q != v.data() + v.size() || (ed != std::errc() && ed != std::errc::result_out_of_range))
        return "expects a number, got '" + s + "'";
    if (ed == std::errc::result_out_of_range) return range;  // "1e400": from_chars left d at 0
    if (std::isnan(d) || (std::isfinite(d) && d != std::floor(d))) return "must be an integer, got '" + s + "'";
    if (!(d >= double(lo) && d <= double(hi))) return range;
    out = static_cast<std::uint64_t>(d);
    return out < lo || out > hi ? range : "";
}

/// CLI11 transform: an integer in [lo, hi], rewritten as plain digits for CLI11's conversion.
inline CLI::Validator count_in(std::uint64_t lo, std::uint64_t hi) {
    return CLI::Validator(
        [lo, hi](std::string& s) {
            std::uint64_t v = 0;
            std::string why = count_problem(s, lo, hi, v);
            if (why.empty()) s = std::to_string(v);
            return why;
        },
        "");
}

/// Parses a finite number ("+" allowed); false for anything else.
inline bool finite_number(std::string_view v, double& out) {
    if (!v.empty() && v[0] == '+') v.remove_prefix(1);
    const auto [p, ec] = std::from_chars(v.data(), v.data() + v.size(), out);
    return !v.empty() && ec == std::errc() && p == v.data() + v.size() && std::isfinite(out) &&
           std::isfinite(static_cast<float>(out));
}

/// CLI11 check: a finite number for which `ok` holds, else `why`.
inline CLI::Validator real_in(std::function<bool(double)> ok, std::string why) {
    return CLI::Validator(
        [ok = std::move(ok), why = std::move(why)](std::string& s) -> std::string {
            double d = 0.0;
            if (!finite_number(s, d)) return "expects a finite number, got '" + s + "'";
            return ok(d) ? "" : why + ", got '" + s + "'";
        },
        "");
}

/// CLI11 check: a finite number (floats: within float range).
inline CLI::Validator finite() {
    return real_in([](double) { return true; }, "");
}

/// CLI11's help, with a multi-value option shown as its value names ("--up UX UY UZ"), not
/// "--up TEXT x 3", and an option whose values are a set (CLI::IsMember, type name "") as the
/// set ("--device {cpu,cl}").
class Formatter : public CLI::Formatter {
public:
    std::string make_option_opts(const CLI::Option* opt) const override {
        std::string type = opt->get_type_size() != 0 ? opt->get_type_name() : std::string();
        if (!type.empty() && type[0] == ':') type.erase(0, 1);
        return type.empty() ? std::string() : " " + type;
    }
    /// Options in the group kDeprecated (old names kept working) are left out of the help; unlike
    /// CLI11's hidden group "", they keep their names in error messages.
    std::string make_group(std::string group, bool is_positional, std::vector<const CLI::Option*> opts) const override {
        return group == kDeprecated ? std::string() : CLI::Formatter::make_group(group, is_positional, opts);
    }
    static constexpr const char* kDeprecated = "Deprecated";
};

/// Parses argv[first ..] with `app`; a CLI11 parse error (--help included) is a UsageError.
inline void parse_args(CLI::App& app, int argc, char** argv, int first) {
    std::vector<std::string> args;
    for (int i = argc - 1; i >= first; --i) args.emplace_back(argv[i]);  // CLI11 takes them reversed
    try {
        app.parse(args);
    } catch (const CLI::ParseError& e) {
        throw UsageError(e.what());
    }
}

}  // namespace raykit_cli
