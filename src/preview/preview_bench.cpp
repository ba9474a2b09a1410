// cambium — the live preview's benchmark.
#include "preview/preview_bench.h"

#include "bench/median.h"
#include "bench/process_run.h"
#include "core/clock.h"
#include "core/error.h"
#include "core/files.h"
#include "model/growth_params.h"
#include "preview/loop.h"
#include "preview/preview.h"
#include "preview/server.h"

#include <fmt/format.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include <condition_variable>
#include <filesystem>
#include <map>
#include <mutex>
#include <thread>
#include <unistd.h>

namespace cambium {

namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

PreviewBenchStage stageOf(const std::vector<double>& v)
{
    return {medianOf(v), *std::min_element(v.begin(), v.end()),
            *std::max_element(v.begin(), v.end())};
}

/// What the loop and the page's client saw, by picture number.
struct Seen {
    std::mutex mutex;
    std::condition_variable changed;
    std::map<size_t, std::pair<Clock::time_point, PreviewUpdate>> written;  // the loop's callback
    std::map<size_t, Clock::time_point> fetched;  // the picture fetched after its event
    std::string failure;
};

void benchYear(const PreviewBenchRequest& req, int yearNumber, const fs::path& dir,
               PreviewBenchYear& out)
{
    const fs::path tree = dir / "tree.json";
    fs::copy_file(req.parameters, tree, fs::copy_options::overwrite_existing);
    out.year = yearNumber;
    // The whole command, as a person starts it (the kernel cache warm: the
    // same command ran before the first year).
    const std::string exe = executableDirectory() + "/cambium";
    const ProcessRun first = runProcess(
        {exe, "preview", tree.string(), "--year", std::to_string(yearNumber), "--once", "--device",
         req.device == Device::OpenCL ? "opencl" : "cpu", "--width", std::to_string(req.width),
         "--height", std::to_string(req.height), "-o", (dir / "once.png").string()},
        (dir / "log.txt").string());
    out.firstCommandSeconds = first.seconds;
    out.firstCommandPeakBytes = first.peakBytes;

    PreviewSettings settings;
    settings.input = tree.string();
    settings.model.time = double(yearNumber);
    settings.device = req.device;
    settings.width = req.width;
    settings.height = req.height;
    settings.output = (dir / "preview.png").string();
    PreviewSession session(settings);
    InotifyChanges changes(settings.input);
    Seen seen;
    PreviewServer server(session, changes);
    std::atomic<bool> stop{false};
    PreviewLoopOptions options;
    options.updated = [&](const PreviewUpdate& u) {
        {
            std::lock_guard<std::mutex> lock(seen.mutex);
            if (u.outcome == PreviewUpdate::Outcome::Rendered)
                seen.written[u.pictures] = {Clock::now(), u};
            else if (u.outcome == PreviewUpdate::Outcome::Failed)
                seen.failure = u.error;
        }
        seen.changed.notify_all();
        server.publish(u);
    };
    // (an exception out of a thread ends the process: the loop's failure,
    // such as the scratch directory removed by a signal's cleanup, is kept
    // for the waits below, which stop on it; a SIGTERM aborted the bench)
    std::thread loop([&] {
        try {
            runPreviewLoop(session, changes, stop, options);
        } catch (const std::exception& e) {
            std::lock_guard<std::mutex> lock(seen.mutex);
            seen.failure = e.what();
            seen.changed.notify_all();
        }
    });
    // The page's side: the events, and each new picture fetched.
    std::thread page([&] {
        try {
            httplib::Client events("127.0.0.1", server.port()),
                pictures("127.0.0.1", server.port());
            events.set_read_timeout(60, 0);
            std::string buffer;
            events.Get(fmt::format("/events?token={}", server.token()).c_str(),
                       [&](const char* data, size_t size) {
                           buffer.append(data, size);
                           for (size_t end; (end = buffer.find("\n\n")) != std::string::npos;) {
                               const std::string message = buffer.substr(0, end);
                               buffer.erase(0, end + 2);
                               const auto at = message.find("data: ");
                               if (at == std::string::npos)
                                   continue;
                               const json u = json::parse(message.substr(at + 6), nullptr, false);
                               if (!u.is_object() || u["outcome"] != "rendered")
                                   continue;
                               pictures.Get(fmt::format("/picture.png?token={}&n={}",
                                                        server.token(), u["picture"].get<size_t>())
                                                .c_str());
                               {
                                   std::lock_guard<std::mutex> lock(seen.mutex);
                                   seen.fetched[u["picture"].get<size_t>()] = Clock::now();
                               }
                               seen.changed.notify_all();
                           }
                           return !stop.load();
                       });
        } catch (const std::exception& e) {  // (the page's side: a reply not as expected)
            std::lock_guard<std::mutex> lock(seen.mutex);
            seen.failure = e.what();
            seen.changed.notify_all();
        }
    });
    struct Stop {
        std::atomic<bool>& stop;
        std::thread &loop, &page;
        PreviewServer& server;
        ~Stop()
        {
            stop = true;
            loop.join();
            PreviewUpdate wake;  // (the page's stream wakes and sees `stop`)
            wake.outcome = PreviewUpdate::Outcome::Failed;
            server.publish(wake);
            page.join();
        }
    } stopper{stop, loop, page, server};
    auto waitForPicture = [&](size_t n) {
        std::unique_lock<std::mutex> lock(seen.mutex);
        if (!seen.changed.wait_for(lock, std::chrono::seconds(120),
                                   [&] { return seen.fetched.count(n) || !seen.failure.empty(); }))
            throw std::runtime_error(
                fmt::format("year {}: picture {} did not come", yearNumber, n));
        if (!seen.failure.empty())
            throw std::runtime_error(fmt::format("year {}: {}", yearNumber, seen.failure));
        return std::pair{seen.written.at(n).first, seen.written.at(n).second};
    };
    out.firstInProcessSeconds = waitForPicture(1).second.total;

    // Edits as the page sends them: the middle point of the mature
    // silhouette Gs2 up and down in turn.
    httplib::Client client("127.0.0.1", server.port());
    std::vector<std::pair<double, double>> gs2 = loadGrowthParameters(tree.string()).Gs2.points();
    const size_t middle = gs2.size() / 2;
    std::vector<double> read, compile, bake, render, write, push, whole;
    for (int i = 0; i < req.edits; ++i) {
        gs2[middle].second += i % 2 ? -0.05 : 0.05;
        json points = json::array();
        for (const auto& [x, y] : gs2)
            points.push_back({x, y});
        const auto sent = Clock::now();
        const auto r =
            client.Post(fmt::format("/curve?token={}", server.token()).c_str(),
                        json{{"key", "Gs2"}, {"points", points}}.dump(), "application/json");
        if (!r || r->status != 200)
            throw std::runtime_error(fmt::format("year {}: the edit was refused: {}", yearNumber,
                                                 r ? r->body : "no answer"));
        const auto [writtenAt, u] = waitForPicture(size_t(i) + 2);
        Clock::time_point fetchedAt;
        {
            std::lock_guard<std::mutex> lock(seen.mutex);
            fetchedAt = seen.fetched.at(size_t(i) + 2);
        }
        read.push_back(u.model);
        compile.push_back(u.compile);
        bake.push_back(u.bake);
        render.push_back(u.render);
        write.push_back(u.write);
        push.push_back(std::chrono::duration<double>(fetchedAt - writtenAt).count());
        whole.push_back(std::chrono::duration<double>(fetchedAt - sent).count());
        out.voxelSize = u.voxelSize;
        out.leaves = u.leaves;
        out.reusedLeaves = u.reusedLeaves;
    }
    out.read = stageOf(read);
    out.compile = stageOf(compile);
    out.bake = stageOf(bake);
    out.render = stageOf(render);
    out.write = stageOf(write);
    out.push = stageOf(push);
    out.editToPicture = stageOf(whole);
}

}  // namespace

void checkPreviewBench(const PreviewBenchRequest& req)
{
    // (each was found by the preview it runs, after the table's header:
    // exit 1, where a bad option is exit 2)
    if (req.edits < 1 || req.edits > 1000000)
        throw InputError(fmt::format("--edits: from 1 to 1000000 (got {})", req.edits));
    if (req.width < 1 || req.width > 16384 || req.height < 1 || req.height > 16384)
        throw InputError(fmt::format("--width and --height: from 1 to 16384 (got {} x {})",
                                     req.width, req.height));
    checkGrowthYears(req.years, loadGrowthParameters(req.parameters), req.parameters);
}

void runPreviewBench(const PreviewBenchRequest& req,
                     const std::function<void(const PreviewBenchYear&)>& year)
{
    checkPreviewBench(req);
    const ScratchDirectory scratch(ScratchDirectory::temporaryPath("bench_preview"));
    const fs::path dir = scratch.path();
    // The kernel cache warmed, as after `cambium prepare` or an earlier run.
    runProcess({executableDirectory() + "/cambium", "prepare"}, (dir / "log.txt").string());
    for (int y : req.years) {
        PreviewBenchYear out;
        benchYear(req, y, dir, out);
        year(out);
    }
}

}  // namespace cambium
