// mtcut: batch front end. Each command is a cmd_*.cpp; see `mtcut help`.
#include "tools/Cli.h"
#include "vdb/SliceExr.h"

#include <openvdb/openvdb.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <exception>
#include <thread>

using namespace mtcut;
using namespace mtcut::cli;

namespace {

void printInputOptions(FILE* out)
{
    std::fprintf(out,
                 "\ninput options (any INPUT: DICOM folder, .nrrd/.nhdr, .nii/.nii.gz, .mha/.mhd, .vdb, raw):\n"
                 "  --series UID        DICOM: read this series (default: the one with most slices)\n"
                 "  --grid NAME         .vdb: read this float grid (default: the first)\n"
                 "  --air V             values <= V are air, stored sparsely (default: -500 HU for CT)\n"
                 "  --dims X,Y,Z --type int8|uint8|int16|uint16|int32|uint32|float32|float64\n"
                 "  [--endian little|big] [--spacing X,Y,Z] [--origin X,Y,Z] [--offset BYTES]\n"
                 "                      raw data layout\n");
}

void printUsage(FILE* out)
{
    std::fprintf(out, "usage: mtcut COMMAND [ARGS]\n\ncommands:\n");
    for (const auto& [name, cmd] : commands()) {
        std::fprintf(out, "  %s\n      %s\n", cmd.usage.c_str(), cmd.summary.c_str());
    }
    std::fprintf(out, "\n'mtcut COMMAND --help' (or 'mtcut help COMMAND') shows one command.\n");
    printInputOptions(out);
}

/// `mtcut COMMAND --help`: the command's usage line, what it does, and the
/// input options when it reads an INPUT.
void printCommandUsage(const Command& cmd, FILE* out)
{
    std::fprintf(out, "usage: mtcut %s\n\n%s\n", cmd.usage.c_str(), cmd.summary.c_str());
    if (std::find(cmd.valueOptions.begin(), cmd.valueOptions.end(), "series") != cmd.valueOptions.end()) {
        printInputOptions(out);
    }
}

/// Is `--help` or `-h` among the command's arguments where an option may
/// stand (not as the value of the option before it)?
bool asksForHelp(const Command& cmd, int argc, char** argv)
{
    for (int i = 2; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--help" || a == "-h") return true;
        const std::string name = a.size() > 2 && a.compare(0, 2, "--") == 0 ? a.substr(2) : std::string();
        const bool takesValue =
            a == "-o" || (!name.empty() && name.find('=') == std::string::npos &&
                          std::find(cmd.valueOptions.begin(), cmd.valueOptions.end(), name) != cmd.valueOptions.end());
        if (takesValue) ++i; // its value, whatever it looks like
    }
    return false;
}

Args parse(const Command& cmd, int argc, char** argv)
{
    Args args;
    auto isValue = [&](const std::string& n) {
        return std::find(cmd.valueOptions.begin(), cmd.valueOptions.end(), n) != cmd.valueOptions.end();
    };
    auto isFlag = [&](const std::string& n) {
        return std::find(cmd.flagOptions.begin(), cmd.flagOptions.end(), n) != cmd.flagOptions.end();
    };
    for (int i = 2; i < argc; ++i) {
        std::string a = argv[i];
        if (a.size() > 2 && a.compare(0, 2, "--") == 0) {
            std::string name = a.substr(2), value;
            const size_t eq = name.find('=');
            const bool inlineValue = eq != std::string::npos;
            if (inlineValue) {
                value = name.substr(eq + 1);
                name = name.substr(0, eq);
            }
            if (isValue(name)) {
                if (!inlineValue) {
                    if (i + 1 >= argc) throw InputError("option --" + name + " needs a value");
                    value = argv[++i];
                }
                args.options[name] = value;
            } else if (isFlag(name) && !inlineValue) {
                args.flags.insert(name);
            } else {
                throw InputError("unknown option " + a + " for 'mtcut " + cmd.name + "' (usage: mtcut " +
                                 cmd.usage + ")");
            }
        } else if (a == "-o") {
            if (!isValue("output")) throw InputError("unknown option -o for 'mtcut " + cmd.name + "'");
            if (i + 1 >= argc) throw InputError("option -o needs a value");
            args.options["output"] = argv[++i];
        } else {
            args.positional.push_back(a);
        }
    }
    if (args.positional.size() < cmd.minPositional || args.positional.size() > cmd.maxPositional) {
        throw InputError("usage: mtcut " + cmd.usage);
    }
    return args;
}

} // namespace

int main(int argc, char** argv)
{
    if (argc >= 3 && !std::strcmp(argv[1], "help")) {
        auto it = commands().find(argv[2]);
        if (it == commands().end()) {
            std::fprintf(stderr, "mtcut: unknown command '%s' (see mtcut help)\n", argv[2]);
            return 2;
        }
        printCommandUsage(it->second, stdout);
        return 0;
    }
    if (argc < 2 || !std::strcmp(argv[1], "help") || !std::strcmp(argv[1], "--help") ||
        !std::strcmp(argv[1], "-h")) {
        printUsage(argc < 2 ? stderr : stdout);
        return argc < 2 ? 2 : 0;
    }
    auto it = commands().find(argv[1]);
    if (it == commands().end()) {
        std::fprintf(stderr, "mtcut: unknown command '%s' (see mtcut help)\n", argv[1]);
        return 2;
    }
    if (asksForHelp(it->second, argc, argv)) {
        printCommandUsage(it->second, stdout);
        return 0;
    }
    try {
        openvdb::initialize();
        vdb::setExrThreadCount(std::thread::hardware_concurrency()); // EXR compression on every core
        const Args args = parse(it->second, argc, argv);
        return it->second.run(args);
    } catch (const InputError& e) {
        std::fprintf(stderr, "mtcut: error: %s\n", e.what());
    } catch (const Cancelled&) {
        std::fprintf(stderr, "mtcut: cancelled\n");
        return 130;
    } catch (const std::bad_alloc&) {
        std::fprintf(stderr, "mtcut: error: out of memory\n");
    } catch (const std::exception& e) {
        std::fprintf(stderr, "mtcut: error: %s\n", e.what());
    }
    return 1;
}
