// The live preview's page server: reachable on 127.0.0.1 only, with its
// token and a loopback Host only; fixed routes (no path reaches a file);
// curve edits checked by the file's reader and written to the watched file
// and nowhere else; the view moved and signalled; updates pushed as
// Server-Sent Events; the model's curves as the reader evaluates them.
#include "preview/server.h"

#include "core/error.h"
#include "model/growth_params.h"

#include "cli_util.h"
#include "temp_dir.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <atomic>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include <arpa/inet.h>
#include <filesystem>
#include <fstream>
#include <netinet/in.h>
#include <set>
#include <sys/socket.h>
#include <thread>
#include <unistd.h>

namespace {

using namespace cambium;
using cambium::test::fileContents;
using json = nlohmann::json;
namespace fs = std::filesystem;

/// Whether a TCP connection to `address`:`port` (IPv4 or IPv6) is accepted.
bool connects(const std::string& address, int port)
{
    sockaddr_storage storage{};
    socklen_t size = 0;
    int family = AF_INET;
    if (address.find(':') != std::string::npos) {
        family = AF_INET6;
        auto* a = reinterpret_cast<sockaddr_in6*>(&storage);
        a->sin6_family = AF_INET6;
        a->sin6_port = htons(uint16_t(port));
        ::inet_pton(AF_INET6, address.c_str(), &a->sin6_addr);
        size = sizeof(sockaddr_in6);
    } else {
        auto* a = reinterpret_cast<sockaddr_in*>(&storage);
        a->sin_family = AF_INET;
        a->sin_port = htons(uint16_t(port));
        ::inet_pton(AF_INET, address.c_str(), &a->sin_addr);
        size = sizeof(sockaddr_in);
    }
    const int fd = ::socket(family, SOCK_STREAM, 0);
    if (fd < 0)
        return false;
    const bool ok = ::connect(fd, reinterpret_cast<sockaddr*>(&storage), size) == 0;
    ::close(fd);
    return ok;
}

/// The status of `GET path` sent to 127.0.0.1:`port` over a connection of
/// its own with exactly the Host header `host`: what a browser sends, with
/// no client library deciding the headers.
int rawStatus(int port, const std::string& path, const std::string& host)
{
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(uint16_t(port));
    ::inet_pton(AF_INET, "127.0.0.1", &a.sin_addr);
    if (fd < 0 || ::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
        if (fd >= 0)
            ::close(fd);
        return -1;
    }
    const std::string request =
        "GET " + path + " HTTP/1.1\r\nHost: " + host + "\r\nConnection: close\r\n\r\n";
    if (::write(fd, request.data(), request.size()) != ssize_t(request.size())) {
        ::close(fd);
        return -1;
    }
    std::string answer;
    char buffer[512];
    while (answer.find("\r\n") == std::string::npos) {
        const ssize_t n = ::read(fd, buffer, sizeof buffer);
        if (n <= 0)
            break;
        answer.append(buffer, size_t(n));
    }
    ::close(fd);
    // "HTTP/1.1 403 Forbidden"
    return answer.size() > 12 ? std::atoi(answer.c_str() + 9) : -1;
}

/// The local addresses (hex, as /proc/net/tcp{,6} writes them) of the
/// sockets listening on `port`.
std::set<std::string> listeningAddresses(int port)
{
    std::set<std::string> out;
    for (const char* table : {"/proc/net/tcp", "/proc/net/tcp6"}) {
        std::ifstream in(table);
        std::string line;
        std::getline(in, line);  // (the header)
        while (std::getline(in, line)) {
            std::istringstream fields(line);
            std::string slot, local, remote, state;
            fields >> slot >> local >> remote >> state;
            const auto colon = local.rfind(':');
            if (state == "0A" && colon != std::string::npos &&
                std::stoi(local.substr(colon + 1), nullptr, 16) == port)
                out.insert(local.substr(0, colon));
        }
    }
    return out;
}

struct Fixture {
    fs::path dir;
    PreviewSession session;
    ManualChanges changes;
    PreviewServer server;
    httplib::Client client;
    std::string token;

    static PreviewSettings settings(const fs::path& dir)
    {
        fs::copy_file(CAMBIUM_SOURCE_DIR "/examples/populus/populus.json", dir / "tree.json");
        PreviewSettings s;
        s.input = (dir / "tree.json").string();
        s.model.time = 3.0;
        s.voxelSize = 0.05;
        s.device = Device::Cpu;
        s.width = 64;
        s.height = 48;
        s.output = (dir / "preview.png").string();
        return s;
    }

    explicit Fixture(const std::string& name)
        : dir(cambium::test::freshDir(name)),
          session(settings(dir)),
          server(session, changes),
          client("127.0.0.1", server.port()),
          token(server.token())
    {
    }
    std::string withToken(const std::string& path) const
    {
        return path + (path.find('?') == std::string::npos ? "?" : "&") + "token=" + token;
    }
    /// The first event a page that connects now is sent: its data, or
    /// null when it is not an update.
    json firstEvent()
    {
        std::string stream;
        client.Get(withToken("/events").c_str(), [&](const char* data, size_t size) {
            stream.append(data, size);
            return stream.find("\n\n") == std::string::npos;
        });
        const std::string head = "event: update\ndata: ";
        if (stream.rfind(head, 0) != 0)
            return nullptr;
        return json::parse(stream.substr(head.size(), stream.find("\n\n") - head.size()));
    }
    httplib::Result post(const std::string& path, const json& body)
    {
        return client.Post(withToken(path).c_str(), body.dump(), "application/json");
    }
};

}  // namespace

TEST(PreviewServer, ListensOnLoopbackOnlyAndAnswersOnlyItsTokenAndHost)
{
    Fixture f("cambium_preview_server_access");
    const int port = f.server.port();
    ASSERT_GT(port, 0);
    EXPECT_EQ(f.server.url(), fmt::format("http://127.0.0.1:{}/?token={}", port, f.token));
    EXPECT_EQ(f.token.size(), 32u);
    // Bound to 127.0.0.1 alone: not to every address, and no other address
    // of the machine (another of the loopback range, IPv6's) reaches it.
    EXPECT_EQ(listeningAddresses(port), std::set<std::string>{"0100007F"});
    EXPECT_TRUE(connects("127.0.0.1", port));
    EXPECT_FALSE(connects("127.0.0.2", port));
    EXPECT_FALSE(connects("::1", port));
    // The page, with the token.
    auto r = f.client.Get(f.withToken("/").c_str());
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 200);
    EXPECT_NE(r->body.find("cambium preview"), std::string::npos);
    // Without it, with another, with a Host that is not the loopback's
    // (a page of another site whose name resolves to 127.0.0.1): refused,
    // on every route, for every method.
    for (const char* path : {"/", "/model", "/picture.png", "/events"}) {
        for (const std::string& query :
             {std::string(""), std::string("?token=0123"),
              "?token=" + f.token.substr(0, 31) + (f.token.back() == '0' ? "1" : "0")}) {
            r = f.client.Get((path + query).c_str());
            ASSERT_TRUE(r);
            EXPECT_EQ(r->status, 403) << path << query;
        }
        for (const std::string& host :
             {std::string("attacker.example"), fmt::format("attacker.example:{}", port),
              fmt::format("127.0.0.1.attacker.example:{}", port)})
            EXPECT_EQ(rawStatus(port, f.withToken(path), host), 403) << path << " " << host;
    }
    r = f.client.Post("/curve", R"({"key": "Gh", "points": [[0, 0], [1, 1]]})", "application/json");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 403);
    EXPECT_EQ(rawStatus(port, f.withToken("/"), fmt::format("localhost:{}", port)), 200);
    EXPECT_EQ(rawStatus(port, f.withToken("/"), fmt::format("127.0.0.1:{}", port)), 200);
}

TEST(PreviewServer, NoPathReachesAFileAndOnlyTheWatchedFileIsWritten)
{
    Fixture f("cambium_preview_server_files");
    const std::string before = fileContents(f.dir / "tree.json");
    std::ofstream(f.dir / "secret.txt") << "not for the page";
    // (What the file system holds around the watched file.)
    for (const char* path :
         {"/../secret.txt", "/..%2fsecret.txt", "/%2e%2e/%2e%2e/etc/passwd",
          "/picture.png/../secret.txt", "/secret.txt", "/tree.json", "//etc/passwd",
          "/events/../secret.txt", "/%252e%252e/secret.txt", "/..%5csecret.txt",
          "/%c0%ae%c0%ae/secret.txt", "/picture.png%00/../secret.txt", "/%2E%2E%2Fsecret.txt",
          "/.%2e/.%2e/secret.txt", "/model/..;/secret.txt", "/%u002e%u002e/secret.txt"}) {
        auto r = f.client.Get(f.withToken(path).c_str());
        ASSERT_TRUE(r) << path;
        EXPECT_NE(r->status, 200) << path;
        EXPECT_EQ(r->body.find("not for the page"), std::string::npos) << path;
        EXPECT_EQ(r->body.find("root:"), std::string::npos) << path;
    }
    // No picture yet: none served.
    auto r = f.client.Get(f.withToken("/picture.png").c_str());
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 404);
    // Bad edits: refused with the reader's words; the file as it was.
    const struct {
        json body;
        std::string expected;
    } bad[] = {
        {{{"key", "Gh"}, {"points", {{0, 0}, {1, 2}}}},
         "curves.Gh: values must be between 0 and 1"},
        {{{"key", "../../secret.txt"}, {"points", {{0, 0}, {1, 1}}}}, "no such curve"},
        {{{"key", "Gh"}, {"points", {{0, 0}, {1, "x"}}}}, "two numbers"},
        {{{"key", "Gh"}, {"file", "secret.txt"}}, "CURVE"},
        {json::array(), "a JSON object"},
        // (a field the edit does not take was dropped, with 200)
        {{{"key", "Gh"}, {"points", {{0, 0}, {1, 1}}}, {"interpolation", "cubic"}},
         "interpolation: not a field of a curve edit"},
    };
    for (const auto& b : bad) {
        r = f.post("/curve", b.body);
        ASSERT_TRUE(r);
        EXPECT_EQ(r->status, 400) << b.body;
        EXPECT_NE(r->body.find(b.expected), std::string::npos) << r->body;
    }
    // A key twice (the last one won) and a number past a double: the
    // files' parser's words.
    for (const auto& [raw, expected] :
         {std::pair<std::string, std::string>{
              R"({"key": "Gh", "key": "Gh", "points": [[0, 0], [1, 1]]})", "duplicate key 'key'"},
          {R"({"key": "Gh", "points": [[0, 0], [1, 1e999]]})", "number overflow"}}) {
        r = f.client.Post(f.withToken("/curve").c_str(), raw, "application/json");
        ASSERT_TRUE(r);
        EXPECT_EQ(r->status, 400) << raw;
        EXPECT_NE(r->body.find(expected), std::string::npos) << r->body;
    }
    EXPECT_EQ(fileContents(f.dir / "tree.json"), before);
    // A good edit: the watched file, and only its curve's points, changed.
    r = f.post("/curve", {{"key", "Gh"}, {"points", {{0, 0.1}, {0.5, 0.5}, {1, 1}}}});
    ASSERT_TRUE(r);
    ASSERT_EQ(r->status, 200) << r->body;
    const std::string after = fileContents(f.dir / "tree.json");
    EXPECT_EQ(after, withCurvePoints(before, "x", "Gh", {{0, 0.1}, {0.5, 0.5}, {1, 1}}));
    EXPECT_DOUBLE_EQ(loadGrowthParameters((f.dir / "tree.json").string()).Gh(0.5), 0.5);
    // Nothing else written: the directory holds what it held.
    std::set<std::string> files;
    for (const auto& entry : fs::directory_iterator(f.dir))
        files.insert(entry.path().filename().string());
    EXPECT_EQ(files, (std::set<std::string>{"secret.txt", "tree.json"}));
    EXPECT_EQ(fileContents(f.dir / "secret.txt"), "not for the page");
}

TEST(PreviewServer, TheModelTheViewAndPushedUpdates)
{
    Fixture f("cambium_preview_server_model");
    // The curves as the reader evaluates them.
    auto r = f.client.Get(f.withToken("/model").c_str());
    ASSERT_TRUE(r);
    ASSERT_EQ(r->status, 200);
    const json model = json::parse(r->body);
    EXPECT_EQ(model["years"], 27);
    EXPECT_EQ(model["view"]["time"], 3.0);
    const GrowthParameters p = loadGrowthParameters(f.session.settings().input);
    ASSERT_EQ(model["curves"].size(), growthCurves().size());
    for (size_t i = 0; i < growthCurves().size(); ++i) {
        const GrowthCurve& c = growthCurves()[i];
        const json& curve = model["curves"][i];
        EXPECT_EQ(curve["key"], c.key);
        EXPECT_EQ(curve["range"], json({c.lo, c.hi}));
        ASSERT_EQ(curve["samples"].size(), 65u);
        for (size_t k = 0; k < 65; ++k)
            EXPECT_EQ(curve["samples"][k].get<double>(), (p.*c.member)(double(k) / 64.0));
    }
    // The view: moved, and the loop told.
    r = f.post("/view", {{"time", 5.5}, {"azimuth", 30}});
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 200) << r->body;
    EXPECT_EQ(f.session.view().time, 5.5);
    EXPECT_EQ(f.session.view().azimuth, 30.0);
    EXPECT_TRUE(f.changes.wait(std::chrono::milliseconds(0)));
    for (const json& body : {json{{"time", -1}}, json{{"azimuth", "left"}}, json{{"zoom", 2}}}) {
        r = f.post("/view", body);
        ASSERT_TRUE(r);
        EXPECT_EQ(r->status, 400) << body;
    }
    EXPECT_EQ(f.session.view().time, 5.5);
    EXPECT_FALSE(f.changes.wait(std::chrono::milliseconds(0)));
    // An update: the picture served, and the update pushed to a page that
    // connects after it.
    const PreviewUpdate u = f.session.update();
    ASSERT_EQ(u.outcome, PreviewUpdate::Outcome::Rendered) << u.error;
    f.server.publish(u);
    r = f.client.Get(f.withToken("/picture.png").c_str());
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 200);
    EXPECT_TRUE(r->body == fileContents(f.dir / "preview.png"));
    const json pushed = f.firstEvent();
    ASSERT_TRUE(pushed.is_object());
    EXPECT_EQ(pushed["outcome"], "rendered");
    EXPECT_EQ(pushed["picture"], 1);
    EXPECT_EQ(pushed["view"]["time"], 5.5);
    EXPECT_EQ(pushed["stages"]["total"], u.total);
}

TEST(PreviewServer, ATakenPortIsBadInputNamed)
{
    Fixture f("cambium_preview_server_port");
    try {
        PreviewServer second(f.session, f.changes, f.server.port());
        ADD_FAILURE() << "two servers on one port";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(std::to_string(f.server.port())), std::string::npos);
    }
}

TEST(PreviewServer, AFileThatIsNotUtf8IsReportedNotFatal)
{
    Fixture f("cambium_preview_server_latin1");
    // A Latin-1 name: the parser's message quotes the byte as it read it.
    std::string text = fileContents(f.dir / "tree.json");
    text.replace(text.find("\"name\": \""), 9, "\"name\": \"Peuplier \xe9 ");
    std::ofstream(f.dir / "tree.json") << text;
    const PreviewUpdate u = f.session.update();
    ASSERT_EQ(u.outcome, PreviewUpdate::Outcome::Failed);
    EXPECT_NO_THROW(f.server.publish(u));
    const auto r = f.client.Get(f.withToken("/model").c_str());
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 200);
    EXPECT_FALSE(json::parse(r->body, nullptr, false).is_discarded());
    // The page is told, in valid JSON.
    const json pushed = f.firstEvent();
    ASSERT_TRUE(pushed.is_object());
    EXPECT_EQ(pushed["outcome"], "failed");
    EXPECT_NE(pushed["error"].get<std::string>().find("tree.json"), std::string::npos);
}

namespace {

/// A TCP connection to 127.0.0.1:`port` (-1 when refused).
int openConnection(int port)
{
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(uint16_t(port));
    ::inet_pton(AF_INET, "127.0.0.1", &a.sin_addr);
    if (fd >= 0 && ::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0)
        return fd;
    if (fd >= 0)
        ::close(fd);
    return -1;
}

/// Everything the server sends on `fd` until it closes the connection (or
/// `seconds` pass with nothing read).
std::string readUntilClosed(int fd, int seconds)
{
    timeval limit{seconds, 0};
    ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &limit, sizeof limit);
    std::string answer;
    char buffer[4096];
    for (;;) {
        const ssize_t n = ::read(fd, buffer, sizeof buffer);
        if (n <= 0)
            return n == 0 ? answer : answer + "<timed out>";
        answer.append(buffer, size_t(n));
    }
}

bool sendAll(int fd, const std::string& bytes)
{
    return ::write(fd, bytes.data(), bytes.size()) == ssize_t(bytes.size());
}

}  // namespace

TEST(PreviewServer, IdleSlowAndManyConnectionsDoNotStallThePage)
{
    Fixture f("cambium_preview_server_load");
    const int port = f.server.port();
    const std::string host = fmt::format("Host: 127.0.0.1:{}\r\n", port);
    // 200 connections that send nothing, and 8 that send half a request and
    // stop (each held by the server until its read times out).
    std::vector<int> idle, slow;
    for (int i = 0; i < 200; ++i)
        idle.push_back(openConnection(port));
    for (int i = 0; i < 8; ++i) {
        slow.push_back(openConnection(port));
        sendAll(slow.back(), "GET " + f.withToken("/model") + " HTTP/1.1\r\nHo");
    }
    for (int fd : idle)
        ASSERT_GE(fd, 0);
    // The page's request is answered beside them.  (A pool of 24 threads
    // held each idle connection for its 2 s timeout: over 16 s for this
    // one; 10 s is what a page can wait.)
    const auto start = std::chrono::steady_clock::now();
    auto r = f.client.Get(f.withToken("/model").c_str());
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 200);
    EXPECT_LT(seconds, 10.0);
    // Connections that send nothing are closed by the server, with nothing
    // sent; the slow ones too.
    for (int fd : idle) {
        EXPECT_EQ(readUntilClosed(fd, 30), "");
        ::close(fd);
    }
    for (int fd : slow) {
        EXPECT_EQ(readUntilClosed(fd, 30).find("<timed out>"), std::string::npos);
        ::close(fd);
    }
    // 300 connections that send a header a byte a second, never ending it,
    // held all 256 threads and the page waited for as long as they dripped
    // (sweep 19): the page is answered beside them.
    std::vector<int> drips;
    for (int i = 0; i < 300; ++i) {
        drips.push_back(openConnection(port));
        ASSERT_GE(drips.back(), 0);
        ASSERT_TRUE(sendAll(drips.back(), "GET /model HTTP/1.1\r\n" + host + "X-Slow: "));
    }
    std::atomic<bool> dripping{true};
    std::thread drip([&] {
        while (dripping) {
            for (int fd : drips)
                sendAll(fd, "a");
            std::this_thread::sleep_for(std::chrono::milliseconds(500));
        }
    });
    std::this_thread::sleep_for(std::chrono::seconds(3));
    const auto dripStart = std::chrono::steady_clock::now();
    auto dripped = f.client.Get(f.withToken("/model").c_str());
    const double dripSeconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - dripStart).count();
    dripping = false;
    drip.join();
    for (int fd : drips)
        ::close(fd);
    ASSERT_TRUE(dripped);
    EXPECT_EQ(dripped->status, 200);
    EXPECT_LT(dripSeconds, 10.0);
    // 200 requests on 200 connections at once: every one answered.
    std::vector<int> many;
    for (int i = 0; i < 200; ++i) {
        many.push_back(openConnection(port));
        ASSERT_GE(many.back(), 0);
        ASSERT_TRUE(sendAll(many.back(), "GET " + f.withToken("/model") + " HTTP/1.1\r\n" + host +
                                             "Connection: close\r\n\r\n"));
    }
    for (int fd : many) {
        const std::string answer = readUntilClosed(fd, 30);
        EXPECT_EQ(answer.rfind("HTTP/1.1 200", 0), 0u) << answer.substr(0, 80);
        EXPECT_NE(answer.find("\"curves\""), std::string::npos);
        ::close(fd);
    }
}

TEST(PreviewServer, HugeAndMalformedRequestsAreRefusedAndNothingIsWritten)
{
    Fixture f("cambium_preview_server_abuse");
    const int port = f.server.port();
    const std::string before = fileContents(f.dir / "tree.json");
    std::ofstream(f.dir / "secret.txt") << "not for the page";
    const std::string host = fmt::format("Host: 127.0.0.1:{}\r\n", port);
    // Bodies: over the 1 MB limit (sent, or only announced), cut short, not
    // JSON, deeply nested, not UTF-8.
    const std::string curve = "POST " + f.withToken("/curve") + " HTTP/1.1\r\n" + host +
                              "Content-Type: application/json\r\nConnection: close\r\n";
    const auto sized = [](const std::string& body) {
        return fmt::format("Content-Length: {}\r\n\r\n", body.size()) + body;
    };
    const struct {
        std::string request;
        const char* status;  // (the answer's first digits; "": any, or none)
    } bad[] = {
        {curve + sized(std::string(2000000, '[')), "413"},
        {curve + "Content-Length: 1000000000000\r\n\r\n{}", "413"},
        {curve + "Content-Length: -5\r\n\r\n{}", "4"},
        {curve + "Content-Length: 10\r\n\r\n{\"ke", ""},  // (cut short)
        {curve + sized("{\"key\": }"), "400"},
        {curve + sized(std::string(100000, '[')), "400"},
        {curve + sized("{\"key\": \"G\xff\", \"points\": [[0,0]]}"), "400"},
        {curve + sized("{\"key\": \"Gh\", \"points\": [[0,0], [1e999, 1]]}"), "400"},
        {curve + "Transfer-Encoding: chunked\r\n\r\nFFFFFFFFFF\r\n{}", ""},
    };
    // (All at once: the ones cut short wait out their timeouts together.)
    std::vector<int> fds;
    for (const auto& b : bad) {
        fds.push_back(openConnection(port));
        ASSERT_GE(fds.back(), 0);
        sendAll(fds.back(), b.request);  // (the connection kept open: the answer is awaited)
    }
    for (size_t i = 0; i < fds.size(); ++i) {
        const auto& b = bad[i];
        const std::string answer = readUntilClosed(fds[i], 30);
        ::close(fds[i]);
        EXPECT_EQ(answer.find("<timed out>"), std::string::npos) << b.request.substr(0, 120);
        const std::string expected = std::string("HTTP/1.1 ") + b.status;
        if (*b.status) {
            EXPECT_EQ(answer.substr(0, expected.size()), expected)
                << b.request.substr(0, 160) << "\n"
                << answer.substr(0, 200);
        }
    }
    // (Paths in every encoding: NoPathReachesAFileAndOnlyTheWatchedFileIsWritten.)
    // The server still serves, and the watched file is as it was.
    auto r = f.client.Get(f.withToken("/model").c_str());
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 200);
    EXPECT_EQ(fileContents(f.dir / "tree.json"), before);
    std::set<std::string> files;
    for (const auto& entry : fs::directory_iterator(f.dir))
        files.insert(entry.path().filename().string());
    EXPECT_EQ(files, (std::set<std::string>{"secret.txt", "tree.json"}));
}
