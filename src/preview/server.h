// cambium — the live preview's web page (cambium preview --port): a server
// on 127.0.0.1 only that shows the latest picture (pushed as Server-Sent
// Events), the year slider and the camera's orbit, the stage timings and any
// error, and an editor for each curve G of a growth parameter file, whose
// edits are checked by the file's own reader and written back to the file:
// the file stays the single source of truth (docs/preview.md).
//
// Every request carries the token printed with the URL and a Host of the
// loopback address (a page of another site cannot reach the server through
// a name that resolves to 127.0.0.1); the server serves its fixed routes
// and nothing from disk but the picture, and writes nothing but the watched
// file.
#pragma once

#include "preview/loop.h"
#include "preview/preview.h"

#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace cambium {

class PreviewServer {
public:
    /// Listens on 127.0.0.1:`port` (0: a free port the system picks) with a
    /// fresh random token; serves from its own threads until destroyed.
    /// InputError when the port cannot be had.  A page edit of the view
    /// (year, camera) goes to `session` and is signalled to `changes`.
    PreviewServer(PreviewSession& session, ChangeSource& changes, int port = 0);
    ~PreviewServer();
    PreviewServer(const PreviewServer&) = delete;
    PreviewServer& operator=(const PreviewServer&) = delete;

    int port() const;
    const std::string& token() const;
    /// http://127.0.0.1:PORT/?token=TOKEN
    std::string url() const;

    /// Tells the open pages what an update did (the loop's callback).
    void publish(const PreviewUpdate& update);

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// The page's HTML, script and style, embedded in the binary.
extern const char* const kPreviewPage;

/// A page's curve edit, from the body of POST /curve: {"key": CURVE,
/// "points": [[x, y], ...]}.  InputError (the server's 400) for a body that
/// is not that JSON object.  (The server's parsers, shared with the fuzzer.)
struct CurveEdit {
    std::string key;
    std::vector<std::pair<double, double>> points;
};
CurveEdit parseCurveEdit(const std::string& body);

/// `view` moved by the body of POST /view: {"time": YEARS or null,
/// "azimuth": DEGREES, "elevation": DEGREES}, any of them.  InputError for
/// another body (a time or angle out of range is PreviewSession's to refuse).
PreviewView parseViewEdit(const std::string& body, PreviewView view);

}  // namespace cambium
