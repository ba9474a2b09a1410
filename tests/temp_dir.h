// cambium tests — a fresh temporary directory a test works in, removed when
// the test process ends however the test went.
#pragma once

#include <filesystem>
#include <mutex>
#include <string>
#include <unistd.h>
#include <vector>

namespace cambium::test {

/// TMPDIR/NAME_PID, emptied and created now, removed at the process's exit.
inline std::filesystem::path freshDir(const std::string& name)
{
    namespace fs = std::filesystem;
    struct Made {
        std::mutex mutex;
        std::vector<fs::path> dirs;
        ~Made()
        {
            std::error_code ec;
            for (const fs::path& d : dirs)
                fs::remove_all(d, ec);
        }
    };
    static Made made;
    const fs::path dir = fs::temp_directory_path() / (name + "_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    std::lock_guard<std::mutex> lock(made.mutex);
    made.dirs.push_back(dir);
    return dir;
}

}  // namespace cambium::test
