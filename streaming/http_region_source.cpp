#include "streaming/http_region_source.h"

#include <curl/curl.h>

#include <mutex>

#include <fmt/format.h>

#include "core/error.h"

namespace lfgi::streaming {

namespace {

struct CurlDeleter {
  void operator()(CURL* c) const { curl_easy_cleanup(c); }
};

// This thread's handle (its connection is kept alive between requests).
CURL* threadHandle() {
  static std::once_flag once;
  std::call_once(once, [] { curl_global_init(CURL_GLOBAL_DEFAULT); });
  thread_local std::unique_ptr<CURL, CurlDeleter> handle(curl_easy_init());
  if (!handle) fail("libcurl: curl_easy_init failed");
  curl_easy_reset(handle.get());
  return handle.get();
}

struct Body {
  std::vector<std::byte> bytes;
  size_t limit = 0;
  bool overflow = false;
};

size_t onData(char* data, size_t size, size_t count, void* user) {
  Body& b = *static_cast<Body*>(user);
  const size_t n = size * count;
  if (b.bytes.size() + n > b.limit) {
    b.overflow = true;
    return 0;  // aborts the transfer
  }
  const auto* p = reinterpret_cast<const std::byte*>(data);
  b.bytes.insert(b.bytes.end(), p, p + n);
  return n;
}

// One GET of url (range "a-b" or empty for the whole file); the body, at most limit bytes.
std::vector<std::byte> request(const std::string& url, const std::string& range, size_t limit,
                               long expectStatus) {
  CURL* c = threadHandle();
  Body body;
  body.limit = limit;
  body.bytes.reserve(range.empty() ? 0 : limit);
  char error[CURL_ERROR_SIZE] = {};
  curl_easy_setopt(c, CURLOPT_URL, url.c_str());
  curl_easy_setopt(c, CURLOPT_WRITEFUNCTION, onData);
  curl_easy_setopt(c, CURLOPT_WRITEDATA, &body);
  curl_easy_setopt(c, CURLOPT_ERRORBUFFER, error);
  curl_easy_setopt(c, CURLOPT_NOSIGNAL, 1L);
  curl_easy_setopt(c, CURLOPT_CONNECTTIMEOUT, 5L);
  curl_easy_setopt(c, CURLOPT_LOW_SPEED_LIMIT, 1024L);
  curl_easy_setopt(c, CURLOPT_LOW_SPEED_TIME, 10L);
  curl_easy_setopt(c, CURLOPT_FOLLOWLOCATION, 1L);
  curl_easy_setopt(c, CURLOPT_MAXREDIRS, 4L);
  if (!range.empty()) curl_easy_setopt(c, CURLOPT_RANGE, range.c_str());
  const CURLcode rc = curl_easy_perform(c);
  if (body.overflow) fail("{}: the response is longer than the {} bytes asked for", url, limit);
  if (rc != CURLE_OK) fail("{}: {}", url, error[0] ? error : curl_easy_strerror(rc));
  long status = 0;
  curl_easy_getinfo(c, CURLINFO_RESPONSE_CODE, &status);
  if (status != expectStatus)
    fail("{}: HTTP status {}{}, expected {}", url, status, range.empty() ? "" : " for range " + range,
         expectStatus);
  return std::move(body.bytes);
}

class HttpSource final : public RegionSource {
 public:
  explicit HttpSource(std::string base) : base_(std::move(base)) {
    if (!base_.empty() && base_.back() != '/') base_ += '/';
  }
  std::vector<std::byte> readAll(const std::string& name, size_t maxBytes) const override {
    return httpGet(locate(name), maxBytes);
  }
  std::vector<std::byte> readRange(const std::string& name, uint64_t offset, uint64_t length) const override {
    const std::string url = locate(name);
    if (length == 0) return {};
    std::vector<std::byte> b =
        request(url, fmt::format("{}-{}", offset, offset + length - 1), size_t(length), 206);
    if (b.size() != length)
      fail("{}: truncated response: {} of the {} bytes at offset {}", url, b.size(), length, offset);
    return b;
  }
  std::string locate(const std::string& name) const override { return base_ + name; }

 private:
  std::string base_;
};

}  // namespace

bool isHttpUrl(const std::string& text) {
  return text.rfind("http://", 0) == 0 || text.rfind("https://", 0) == 0;
}

std::vector<std::byte> httpGet(const std::string& url, size_t maxBytes) {
  return request(url, "", maxBytes, 200);
}

std::shared_ptr<const RegionSource> httpRegionSource(std::string baseUrl) {
  return std::make_shared<HttpSource>(std::move(baseUrl));
}

}  // namespace lfgi::streaming
