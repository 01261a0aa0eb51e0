#include "tools/view/Script.h"

#include "tools/Cli.h"
#include "vdb/Error.h"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>

namespace mtcut::view {

namespace {

std::string trim(const std::string& s)
{
    const char* ws = " \t\r\n";
    const size_t a = s.find_first_not_of(ws);
    if (a == std::string::npos) return {};
    return s.substr(a, s.find_last_not_of(ws) - a + 1);
}

double numberOf(const std::string& text, const std::string& where, bool nonNegative)
{
    char* end = nullptr;
    const double v = std::strtod(text.c_str(), &end);
    if (text.empty() || *end != '\0' || !std::isfinite(v) || (nonNegative && v < 0.0)) {
        throw InputError(where + ": expected " + (nonNegative ? "a number >= 0" : "a finite number") + ", got '" +
                         text + "'");
    }
    return v;
}

} // namespace

std::vector<ScriptAction> parseScript(const std::string& text, const std::string& source)
{
    struct Spec
    {
        const char* name;
        ScriptAction::Kind kind;
        bool takesArgument;
    };
    static const Spec kSpecs[] = {
        {"iso", ScriptAction::Kind::Iso, true},       {"view", ScriptAction::Kind::View, true},
        {"kerf", ScriptAction::Kind::Kerf, true},     {"retrace", ScriptAction::Kind::Retrace, true},
        {"slide", ScriptAction::Kind::Slide, true},   {"path", ScriptAction::Kind::Path, true},
        {"drag", ScriptAction::Kind::Drag, true},     {"pick", ScriptAction::Kind::Pick, true},
        {"undo", ScriptAction::Kind::Undo, false},    {"redo", ScriptAction::Kind::Redo, false},
        {"screenshot", ScriptAction::Kind::Screenshot, true}, {"window", ScriptAction::Kind::Window, true},
        {"export", ScriptAction::Kind::Export, true}, {"export-selected", ScriptAction::Kind::ExportSelected, true},
        {"wait", ScriptAction::Kind::Wait, true},     {"quit", ScriptAction::Kind::Quit, false},
    };
    std::vector<ScriptAction> actions;
    std::istringstream in(text);
    std::string raw;
    for (size_t lineNo = 1; std::getline(in, raw); ++lineNo) {
        const std::string line = trim(raw);
        if (line.empty() || line[0] == '#') continue;
        const size_t space = line.find_first_of(" \t");
        const std::string word = line.substr(0, space);
        const std::string rest = space == std::string::npos ? std::string() : trim(line.substr(space));
        const std::string where = source + ":" + std::to_string(lineNo);
        const Spec* spec = nullptr;
        for (const Spec& s : kSpecs) {
            if (word == s.name) spec = &s;
        }
        if (!spec) {
            throw InputError(where + ": unknown action '" + word +
                             "' (expected iso, view, kerf, retrace, slide, path, drag, pick, undo, redo, screenshot, window, export, export-selected, wait or quit)");
        }
        if (spec->takesArgument && rest.empty()) throw InputError(where + ": " + word + " needs an argument");
        if (!spec->takesArgument && !rest.empty()) {
            throw InputError(where + ": " + word + " takes no argument, got '" + rest + "'");
        }
        ScriptAction a;
        a.kind = spec->kind;
        a.argument = rest;
        a.line = lineNo;
        if (a.kind == ScriptAction::Kind::Iso) a.number = numberOf(rest, where + ": iso", false);
        if (a.kind == ScriptAction::Kind::Kerf) a.number = numberOf(rest, where + ": kerf", true);
        if (a.kind == ScriptAction::Kind::Retrace)
            a.number = cli::filterToleranceWith(numberOf(rest, where + ": retrace", true), where + ": retrace " + rest,
                                                cutter::PathFilterOptions{}.retraceTolerance);
        if (a.kind == ScriptAction::Kind::Slide)
            a.number = cli::filterToleranceWith(numberOf(rest, where + ": slide", true), where + ": slide " + rest,
                                                cutter::PathFilterOptions{}.slideTolerance);
        if (a.kind == ScriptAction::Kind::Wait) {
            if (rest == "poses") a.kind = ScriptAction::Kind::WaitPoses;
            else a.number = numberOf(rest, where + ": wait (seconds, or 'poses')", true);
        }
        if (a.kind == ScriptAction::Kind::Drag) {
            std::istringstream words(rest);
            double v[4];
            std::string extra;
            if (!(words >> v[0] >> v[1] >> v[2] >> v[3]) || (words >> extra)) {
                throw InputError(where + ": drag: expected X0 Y0 X1 Y1 (pixels), got '" + rest + "'");
            }
        }
        if (a.kind == ScriptAction::Kind::Pick) {
            std::istringstream words(rest);
            double v[2];
            std::string extra;
            if (!(words >> v[0] >> v[1]) || (words >> extra)) {
                throw InputError(where + ": pick: expected X Y (pixels), got '" + rest + "'");
            }
        }
        actions.push_back(std::move(a));
    }
    return actions;
}

std::vector<ScriptAction> readScript(const std::string& path)
{
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(path + ": cannot read the script (" + std::strerror(errno) + ")");
    std::ostringstream text;
    text << in.rdbuf();
    return parseScript(text.str(), path);
}

} // namespace mtcut::view
