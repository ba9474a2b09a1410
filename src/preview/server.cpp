// cambium — the live preview's web page, served with cpp-httplib (Debian's
// libcpp-httplib-dev 0.11): a small, maintained server whose chunked
// responses carry Server-Sent Events, which is all the page needs to be
// pushed (docs/preview.md says why not a WebSocket library).
#include "preview/server.h"

#include "core/error.h"
#include "core/files.h"
#include "core/json.h"
#include "core/math.h"
#include "model/growth_params.h"

#include <fmt/format.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include <atomic>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <fstream>
#include <iterator>
#include <functional>
#include <memory>
#include <mutex>
#include <pthread.h>
#include <random>
#include <sys/socket.h>
#include <system_error>
#include <thread>

namespace cambium {

namespace {

using json = nlohmann::json;

/// Connections served at once (each on a thread of its own), and each
/// thread's stack: 300 connections that each sent a byte of a header a
/// second held all of 256 threads, and the page's requests waited for as long
/// as they dripped (sweep 19).  A thread's stack is address space, mostly
/// untouched: 1024 of them reserve 2 GB (std::thread's 8 MB each would
/// reserve 8 GB), and the process's descriptors (`ulimit -n`, often 1024)
/// bound the connections before them.
constexpr size_t kConnectionThreads = 1024;
constexpr size_t kConnectionStack = size_t(2) << 20;

/// A thread of its own stack size (std::thread's is the process's default).
class StackThread {
public:
    StackThread(size_t stackBytes, std::function<void()> fn)
        : fn_(std::make_unique<std::function<void()>>(std::move(fn)))
    {
        pthread_attr_t attr;
        ::pthread_attr_init(&attr);
        ::pthread_attr_setstacksize(&attr, stackBytes);
        const int err = ::pthread_create(&id_, &attr, &StackThread::run, fn_.get());
        ::pthread_attr_destroy(&attr);
        if (err != 0)
            throw std::system_error(err, std::generic_category(), "pthread_create");
    }
    ~StackThread() { ::pthread_join(id_, nullptr); }
    StackThread(const StackThread&) = delete;
    StackThread& operator=(const StackThread&) = delete;

private:
    static void* run(void* fn)
    {
        (*static_cast<std::function<void()>*>(fn))();
        return nullptr;
    }
    pthread_t id_{};
    std::unique_ptr<std::function<void()>> fn_;
};

/// 128 random bits from the system's source, as hex.
std::string randomToken()
{
    std::random_device device;  // (getrandom on Linux)
    std::string token;
    for (int i = 0; i < 4; ++i)
        token += fmt::format("{:08x}", uint32_t(device()));
    return token;
}

/// Equal strings, in a time that does not depend on where they differ.
bool sameSecret(const std::string& a, const std::string& b)
{
    if (a.size() != b.size())
        return false;
    unsigned char diff = 0;
    for (size_t i = 0; i < a.size(); ++i)
        diff |= static_cast<unsigned char>(a[i] ^ b[i]);
    return diff == 0;
}

const char* outcomeName(PreviewUpdate::Outcome o)
{
    switch (o) {
        case PreviewUpdate::Outcome::Rendered:
            return "rendered";
        case PreviewUpdate::Outcome::Unchanged:
            return "unchanged";
        case PreviewUpdate::Outcome::Failed:
            return "failed";
        case PreviewUpdate::Outcome::Interrupted:
            return "interrupted";
    }
    return "";
}

json viewJson(const PreviewView& v)
{
    return {{"time", v.time ? json(*v.time) : json(nullptr)},
            {"azimuth", v.azimuth},
            {"elevation", v.elevation}};
}

json updateJson(const PreviewUpdate& u)
{
    return {{"outcome", outcomeName(u.outcome)},
            {"error", u.error},
            {"picture", u.pictures},
            {"rebaked", u.rebaked},
            {"stages",
             {{"read", u.model},
              {"compile", u.compile},
              {"bake", u.bake},
              {"render", u.render},
              {"write", u.write},
              {"total", u.total}}},
            {"voxel_size", u.voxelSize},
            {"leaves", u.leaves},
            {"reused", u.reusedLeaves},
            {"view", viewJson(u.view)}};
}

/// JSON text of `j`; bytes that are not UTF-8 (a file name, a parser's
/// quote of a Latin-1 file) replaced rather than thrown on.
std::string jsonText(const json& j)
{
    return j.dump(-1, ' ', false, json::error_handler_t::replace);
}

void reply(httplib::Response& res, int status, const json& body)
{
    res.status = status;
    res.set_content(jsonText(body), "application/json");
}

void refuse(httplib::Response& res, int status, const std::string& why)
{
    reply(res, status, {{"error", why}});
}

/// Runs each connection on a thread of its own, up to `most` at once (the
/// rest wait their turn), and keeps the threads for the next connections.
/// A fixed pool of N threads (httplib's) is stalled by N connections that
/// send nothing, each held until its timeout; here an idle or slow client
/// holds only its own thread, and a page's request is answered beside them.
class ConnectionThreads final : public httplib::TaskQueue {
public:
    explicit ConnectionThreads(size_t most) : most_(most) {}
    ~ConnectionThreads() override { shutdown(); }

    void enqueue(std::function<void()> fn) override
    {
        std::lock_guard<std::mutex> lock(mutex_);
        jobs_.push_back(std::move(fn));
        if (jobs_.size() > idle_ && threads_.size() < most_) {
            try {
                threads_.push_back(
                    std::make_unique<StackThread>(kConnectionStack, [this] { work(); }));
                return;
            } catch (const std::exception&) {
                // (no thread to be had: the ones there serve it in turn)
            }
        }
        ready_.notify_one();
    }

    /// Serves what is queued, then joins every thread (httplib calls it when
    /// its accept loop ends: nothing is queued after).
    void shutdown() override
    {
        std::vector<std::unique_ptr<StackThread>> threads;
        {
            std::lock_guard<std::mutex> lock(mutex_);
            stopping_ = true;
            threads.swap(threads_);
        }
        ready_.notify_all();
        threads.clear();  // (each joined)
    }

private:
    void work()
    {
        std::unique_lock<std::mutex> lock(mutex_);
        for (;;) {
            ++idle_;
            ready_.wait(lock, [&] { return stopping_ || !jobs_.empty(); });
            --idle_;
            if (jobs_.empty())
                return;  // (stopping, and nothing left to serve)
            std::function<void()> job = std::move(jobs_.front());
            jobs_.pop_front();
            lock.unlock();
            job();
            lock.lock();
        }
    }

    const size_t most_;
    std::mutex mutex_;
    std::condition_variable ready_;
    std::deque<std::function<void()>> jobs_;
    std::vector<std::unique_ptr<StackThread>> threads_;
    size_t idle_ = 0;
    bool stopping_ = false;
};

}  // namespace

namespace {

/// The request's body as a JSON object, else InputError.
json jsonObject(const std::string& body)
{
    // The files' parser (a duplicate key refused, a number that overflows
    // named as such), then an object.
    json j = parseJson(body, "the request's body");
    if (!j.is_object())
        throw InputError("the request's body must be a JSON object");
    return j;
}

}  // namespace

CurveEdit parseCurveEdit(const std::string& body)
{
    const json j = jsonObject(body);
    // (anything else, such as an interpolation, was dropped with 200)
    for (const auto& [key, value] : j.items())
        if (key != "key" && key != "points")
            throw InputError(fmt::format(
                "{}: not a field of a curve edit (expected {{\"key\": CURVE, \"points\": [[x, y], "
                "...]}}; a curve's interpolation is edited in the file)",
                printable(key)));
    if (!j.contains("key") || !j["key"].is_string() || !j.contains("points") ||
        !j["points"].is_array())
        throw InputError("expected {\"key\": CURVE, \"points\": [[x, y], ...]}");
    CurveEdit edit;
    edit.key = j["key"].get<std::string>();
    for (const json& p : j["points"]) {
        if (!p.is_array() || p.size() != 2 || !p[0].is_number() || !p[1].is_number())
            throw InputError("each point must be [x, y], two numbers");
        edit.points.emplace_back(p[0].get<double>(), p[1].get<double>());
    }
    return edit;
}

PreviewView parseViewEdit(const std::string& body, PreviewView v)
{
    const json j = jsonObject(body);
    for (const auto& [key, value] : j.items()) {
        if (key == "time" && value.is_null())
            v.time.reset();
        else if (key == "time" && value.is_number() && value.get<double>() >= 0.0 &&
                 value.get<double>() <= kFarthestCoordinate)
            v.time = value.get<double>();
        else if ((key == "azimuth" || key == "elevation") && value.is_number() &&
                 std::isfinite(value.get<double>()))
            (key == "azimuth" ? v.azimuth : v.elevation) = value.get<double>();
        else
            throw InputError(fmt::format(
                "{}: expected time (years or null), azimuth or elevation (degrees)", key));
    }
    return v;
}

struct PreviewServer::Impl {
    PreviewSession& session;
    ChangeSource& changes;
    httplib::Server server;
    std::string token = randomToken();
    int port = 0;
    socket_t listening = INVALID_SOCKET;  // (httplib's, closed by it)
    std::thread thread;
    std::atomic<bool> listened{false};  // the listening loop has returned

    // The updates the pages are told of: the count and the latest.
    std::mutex mutex;
    std::condition_variable published;
    size_t events = 0;
    std::string latest;  // the latest update's JSON ("" before the first)
    bool stopping = false;
    std::mutex fileMutex;  // one page edit of the file at a time
    std::mutex viewMutex;  // one page edit of the view at a time (read, changed, set)

    Impl(PreviewSession& s, ChangeSource& c) : session(s), changes(c) {}

    bool allowedHost(const std::string& host) const
    {
        return host == fmt::format("127.0.0.1:{}", port) ||
               host == fmt::format("localhost:{}", port);
    }

    /// The model file as the page shows it: its curves with the values the
    /// reader gives them (the page draws them the same way: the browser test
    /// compares), the years, the view; or the error that stops it reading.
    json model()
    {
        const std::string& input = session.settings().input;
        json out = {{"file", input},
                    {"view", viewJson(session.view())},
                    {"curves", json::array()},
                    {"years", nullptr},
                    {"error", nullptr}};
        if (!isGrowthParameterFile(input))
            return out;
        try {
            const GrowthParameters p = loadGrowthParameters(input);
            out["years"] = p.years;
            for (const GrowthCurve& c : growthCurves()) {
                const Curve& curve = p.*c.member;
                json points = json::array(), samples = json::array();
                for (const auto& [x, y] : curve.points())
                    points.push_back({x, y});
                constexpr int kSamples = 64;
                for (int i = 0; i <= kSamples; ++i)
                    samples.push_back(curve(double(i) / kSamples));
                out["curves"].push_back(
                    {{"key", c.key},
                     {"points", points},
                     {"interpolation",
                      curve.interpolation() == Curve::Interpolation::Smooth ? "smooth" : "linear"},
                     {"range", {c.lo, c.hi}},
                     {"samples", samples}});
            }
        } catch (const std::exception& e) {
            out["error"] = e.what();
        }
        return out;
    }

    /// A page's curve edit: checked by the file's reader, then written over
    /// the file through the checked writer.  The watcher sees the write.
    void editCurve(const std::string& body, httplib::Response& res)
    {
        const std::string& input = session.settings().input;
        std::lock_guard<std::mutex> lock(fileMutex);
        try {
            const CurveEdit edit = parseCurveEdit(body);
            const std::string edited =
                withCurvePoints(readTextFile(input, "model"), input, edit.key, edit.points);
            writeFile(input, edited.data(), edited.size());
        } catch (const InputError& e) {
            return refuse(res, 400, e.what());
        } catch (const std::exception& e) {
            return refuse(res, 500, e.what());
        }
        reply(res, 200, {{"written", input}});
    }

    /// A page's move of the year slider or the camera.
    void editView(const std::string& body, httplib::Response& res)
    {
        std::lock_guard<std::mutex> lock(viewMutex);
        PreviewView v;
        try {
            v = parseViewEdit(body, session.view());
            session.setView(v);
        } catch (const InputError& e) {
            return refuse(res, 400, e.what());
        }
        changes.notify();
        reply(res, 200, {{"view", viewJson(v)}});
    }

    void routes()
    {
        // Every request: the loopback Host and the token, or nothing.
        server.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
            res.set_header("Cache-Control", "no-store");
            res.set_header("Referrer-Policy", "no-referrer");
            res.set_header("X-Content-Type-Options", "nosniff");
            if (!allowedHost(req.get_header_value("Host"))) {
                refuse(res, 403, "this server answers requests for 127.0.0.1 only");
                return httplib::Server::HandlerResponse::Handled;
            }
            if (!sameSecret(req.get_param_value("token"), token)) {
                refuse(res, 403, "missing or wrong token: open the URL cambium preview printed");
                return httplib::Server::HandlerResponse::Handled;
            }
            return httplib::Server::HandlerResponse::Unhandled;
        });
        server.Get("/", [](const httplib::Request&, httplib::Response& res) {
            res.set_header("Content-Security-Policy",
                           "default-src 'none'; script-src 'unsafe-inline'; style-src "
                           "'unsafe-inline'; img-src 'self'; connect-src 'self'; "
                           "frame-ancestors 'none'");
            res.set_content(kPreviewPage, "text/html; charset=utf-8");
        });
        server.Get("/picture.png", [this](const httplib::Request&, httplib::Response& res) {
            // (Written by renaming: this reads one whole picture.)
            std::ifstream in(session.settings().output, std::ios::binary);
            if (!in)
                return refuse(res, 404, "no picture yet");
            std::string bytes((std::istreambuf_iterator<char>(in)),
                              std::istreambuf_iterator<char>());
            if (!in.good() && !in.eof())
                return refuse(res, 500, "the picture cannot be read");
            if (bytes.empty())
                return refuse(res, 404, "no picture yet");
            res.set_content(bytes, "image/png");
        });
        server.Get("/model", [this](const httplib::Request&, httplib::Response& res) {
            reply(res, 200, model());
        });
        server.Post("/curve", [this](const httplib::Request& req, httplib::Response& res) {
            editCurve(req.body, res);
        });
        server.Post("/view", [this](const httplib::Request& req, httplib::Response& res) {
            editView(req.body, res);
        });
        server.Get("/events", [this](const httplib::Request&, httplib::Response& res) {
            // Each page gets the latest update at once, then each new one;
            // a comment every 5 s keeps the connection open and finds a
            // closed one (each open stream holds one of the server's
            // threads).
            auto seen = std::make_shared<size_t>(0);
            res.set_chunked_content_provider(
                "text/event-stream", [this, seen](size_t, httplib::DataSink& sink) {
                    std::unique_lock<std::mutex> lock(mutex);
                    published.wait_for(lock, std::chrono::seconds(5),
                                       [&] { return stopping || events > *seen; });
                    if (stopping || !sink.is_writable())
                        return false;
                    std::string message = ": still here\n\n";
                    if (events > *seen && !latest.empty())
                        message = "event: update\ndata: " + latest + "\n\n";
                    *seen = events;
                    lock.unlock();
                    return sink.write(message.data(), message.size());
                });
        });
        server.set_error_handler([](const httplib::Request&, httplib::Response& res) {
            // (a body too large was answered "no such page")
            if (res.body.empty())
                refuse(res, res.status,
                       res.status == 404   ? std::string("no such page")
                       : res.status == 413 ? std::string("the request's body is too large")
                       : res.status == 400 ? std::string("a malformed request")
                                           : fmt::format("HTTP status {}", res.status));
        });
    }
};

PreviewServer::PreviewServer(PreviewSession& session, ChangeSource& changes, int port)
    : impl_(std::make_unique<Impl>(session, changes))
{
    if (port < 0 || port > 65535)
        throw InputError(fmt::format("--port must be 0 (any free port) to 65535 (got {})", port));
    Impl& s = *impl_;
    s.server.set_payload_max_length(1 << 20);
    // A thread for each connection, bounded (a thread's stack is mostly
    // untouched: 256 idle connections cost a few MB), and connections that
    // send nothing for 2 s closed: a browser opens a new one when it needs
    // it, and the page's event stream writes every 5 s.
    s.server.new_task_queue = [] { return new ConnectionThreads(kConnectionThreads); };
    s.server.set_keep_alive_timeout(2);
    s.server.set_read_timeout(2, 0);
    s.server.set_write_timeout(5, 0);
    // SO_REUSEADDR (a restart finds the port free at once), and not
    // httplib's SO_REUSEPORT, with which a second server on the port would
    // share its connections instead of being refused.
    s.server.set_socket_options([&s](socket_t sock) {
        const int yes = 1;
        ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
        s.listening = sock;
    });
    s.routes();
    // Loopback only: no other address of the machine reaches it.
    if (port == 0) {
        s.port = s.server.bind_to_any_port("127.0.0.1");
    } else {
        s.port = s.server.bind_to_port("127.0.0.1", port) ? port : -1;
    }
    if (s.port <= 0)
        throw InputError(
            fmt::format("--port {}: cannot listen on 127.0.0.1:{} (in use?)", port, port));
    // httplib listens with a backlog of 5: a burst of connections (a page's
    // requests beside idle ones) past it has its SYNs dropped and retried by
    // the client 1, 3, 7 s later.  Listening again sets the queue's length.
    if (s.listening != INVALID_SOCKET)
        ::listen(s.listening, SOMAXCONN);
    s.thread = std::thread([&s] {
        s.server.listen_after_bind();
        s.listened = true;
    });
    // Running before anything can stop it (httplib's stop does nothing to a
    // server that has not started its loop yet).
    while (!s.server.is_running() && !s.listened)
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
}

PreviewServer::~PreviewServer()
{
    {
        std::lock_guard<std::mutex> lock(impl_->mutex);
        impl_->stopping = true;
    }
    impl_->published.notify_all();
    impl_->server.stop();
    impl_->thread.join();
}

int PreviewServer::port() const
{
    return impl_->port;
}

const std::string& PreviewServer::token() const
{
    return impl_->token;
}

std::string PreviewServer::url() const
{
    return fmt::format("http://127.0.0.1:{}/?token={}", impl_->port, impl_->token);
}

void PreviewServer::publish(const PreviewUpdate& update)
{
    if (update.outcome == PreviewUpdate::Outcome::Unchanged)
        return;
    {
        std::lock_guard<std::mutex> lock(impl_->mutex);
        impl_->latest = jsonText(updateJson(update));
        ++impl_->events;
    }
    impl_->published.notify_all();
}

}  // namespace cambium
