// HttpRegionSource: a baked world's region files (core/region_file.h, core/cell_store.h) read from a
// static HTTP server or object store with range requests (libcurl), like map tiles: BASE/regions.json is
// fetched whole, every cell is one `Range: bytes=a-b` request of its region file (the head once per
// region). Any server that answers ranges with 206 works (nginx, S3, a CDN); the files are immutable, so
// responses may be cached forever.
//
// Every failure is an lfgi::Error naming the URL: connection refused or dropped, a timeout (connect 5 s;
// a transfer stalled below 1 KB/s for 10 s), an HTTP status other than 206 (200 for a whole-file read), a
// response longer than asked for (refused as it arrives) or shorter (a truncated response). The streaming
// manager logs a failed load and keeps the cell's fallback, so a dead server degrades the light to the
// coarse fallback, never to a hole. Thread-safe: each calling thread keeps its own connection (reused).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/cell_store.h"

namespace lfgi::streaming {

// Whether text names an HTTP(S) URL ("http://" or "https://").
bool isHttpUrl(const std::string& text);

// GET of a whole small file at url (at most maxBytes); throws lfgi::Error naming the URL.
std::vector<std::byte> httpGet(const std::string& url, size_t maxBytes);

// The region source under baseUrl (the regions directory's URL, with or without a trailing '/').
std::shared_ptr<const RegionSource> httpRegionSource(std::string baseUrl);

}  // namespace lfgi::streaming
