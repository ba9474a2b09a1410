// cambium — the command-line tool: a table of commands (src/app/, one file
// each), the exit status and the last word on errors.
#include "app/app.h"
#include "core/error.h"
#include "core/files.h"
#include "core/process.h"
#include "core/system.h"
#include "core/versions.h"

#include <CLI/CLI.hpp>
#include <openvdb/openvdb.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <new>
#include <stdexcept>
#include <string>

namespace {

/// The commands, in the order `cambium --help` lists them.
const cambium::AddCommand kCommands[] = {
    cambium::addInfoCommand,    cambium::addEvalCommand,   cambium::addBakeCommand,
    cambium::addMeshCommand,    cambium::addRenderCommand, cambium::addBenchCommand,
    cambium::addLSystemCommand, cambium::addGrowthCommand, cambium::addShapeCommand,
    cambium::addPrepareCommand, cambium::addFarmCommand,   cambium::addPreviewCommand,
    cambium::addVersionCommand,
};

/// Runs before the libraries' initializers (ELF preinit_array: the
/// executable's only).
void beforeTheLibraries(int, char**, char**)
{
    cambium::checkRoomToStart();
}
[[gnu::section(".preinit_array"),
  gnu::used]] void (*kBeforeTheLibraries)(int, char**, char**) = beforeTheLibraries;

}  // namespace

int main(int argc, char** argv)
{
    CLI::App app{
        "cambium: bake BlobTree implicit models of growing plants into OpenVDB level sets"};
    app.require_subcommand(1);
    app.set_version_flag("--version", std::string("cambium ") + cambium::version());
    cambium::Action action;
    for (cambium::AddCommand add : kCommands)
        add(app, action);
    cambium::checkOptionValues(app);

    // Exit status (docs/errors.md): 0 success; 2 a bad request, named before
    // any work (a farm must not retry); 1 a failure during the work.
    cambium::installCleanupOnSignals();
    cambium::installMemoryReserve();
    cambium::endWithParent();
    std::string names;
    bool known = false;
    for (const CLI::App* c : app.get_subcommands({})) {
        names += (names.empty() ? "" : ", ") + c->get_name();
        known = known || (argc >= 2 && c->get_name() == argv[1]);
    }
    if (argc >= 2 && argv[1][0] != '-' && !known) {
        std::fprintf(stderr, "cambium: error: unknown command '%s' (the commands: %s)\n",
                     cambium::printable(argv[1]).c_str(), names.c_str());
        return 2;
    }
    // A message is one line, its control characters (a newline or an
    // escape sequence in a file name) shown escaped, not sent to the
    // terminal.  (std::fprintf: never throws, whatever stderr is.)
    auto say = [](const char* how, const char* what) {
        std::string line;
        try {
            // (escaped, then shortened: a control character is 4 bytes
            // escaped, and a message at most 1000 bytes with its prefix)
            line = cambium::shortened(cambium::printable(what), 1000 - 11 - std::strlen(how));
        } catch (...) {
            line = what;
        }
        std::fprintf(stderr, "cambium: %s: %s\n", how, line.c_str());
    };
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        if (e.get_exit_code() == 0)  // --help and --version are not errors
            return app.exit(e);
        // One line, as every other error (CLI11's own adds a second).
        const std::string where = argc >= 2 && known ? std::string(" ") + argv[1] : "";
        say("error",
            (e.what() + std::string(" (cambium") + where + " --help lists the options)").c_str());
        return 2;
    }
    openvdb::initialize();
    try {
        const int status = action ? action() : 0;
        // What the command printed, written to the end (`info > /dev/full`
        // lost its report with exit 0).
        // (errno is the flush's own: a write that failed earlier, with
        // nothing left to flush, says so rather than a stale error)
        errno = 0;
        const bool flushed = std::fflush(stdout) == 0;
        const int error = errno;
        if (!flushed || std::ferror(stdout)) {
            std::fprintf(
                stderr, "cambium: failed: cannot write to standard output: %s\n",
                !flushed && error != 0 ? std::strerror(error) : "a write to it failed earlier");
            return 1;
        }
        return status;
    } catch (const cambium::InputError& e) {
        say("error", e.what());
        return 2;
    } catch (const std::bad_alloc&) {
        std::fprintf(stderr, "cambium: failed: out of memory\n");
        return 1;
    } catch (const std::length_error& e) {  // a container asked for more than memory holds
        say("failed",
            (std::string("out of memory: a buffer larger than any memory was asked for (") +
             e.what() + ")")
                .c_str());
        return 1;
    } catch (const std::exception& e) {
        say("failed", e.what());
        return 1;
    }
}
