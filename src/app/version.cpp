// cambium version — cambium's version, its libraries' and the OpenCL devices.
#include "app/app.h"

#include "cl/runtime.h"
#include "core/versions.h"

#include <fmt/format.h>

namespace cambium {

namespace {

int runVersion()
{
    fmt::print("cambium {}\n", version());
    for (const auto& [lib, v] : dependencyVersions())
        fmt::print("  {:<12} {}\n", lib, v);
    const auto devices = listOpenCLDevices();
    if (devices.empty())
        fmt::print("  {:<12} {}\n", "OpenCL", "no platform found");
    for (const auto& d : devices)
        fmt::print("  {:<12} {} / {} / {}\n", "OpenCL", d.platform, d.device, d.version);
    return 0;
}

}  // namespace

void addVersionCommand(CLI::App& app, Action& action)
{
    auto* cmd = app.add_subcommand("version",
                                   "Print the versions of cambium, its libraries and the "
                                   "OpenCL devices found");
    cmd->callback([&action] { action = [] { return runVersion(); }; });
}

}  // namespace cambium
