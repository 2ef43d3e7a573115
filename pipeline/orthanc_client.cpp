#include "pipeline/orthanc_client.h"

#include <cstdio>
#include <memory>

#include <curl/curl.h>

#include "core/error.h"
#include "core/files.h"

namespace ms::pipeline {

namespace {

// Seconds a request may take: a series archive of a few hundred MB on a LAN,
// with a wide margin; connecting must be quick (loopback or LAN).
constexpr long kRequestTimeoutS = 600;
constexpr long kConnectTimeoutS = 10;

std::size_t to_string(char* data, std::size_t size, std::size_t n, void* out) {
  static_cast<std::string*>(out)->append(data, size * n);
  return size * n;
}

std::size_t to_file(char* data, std::size_t size, std::size_t n, void* out) {
  return std::fwrite(data, size, n, static_cast<std::FILE*>(out)) * size;
}

}  // namespace

OrthancClient::OrthancClient(std::string url, std::string credentials) : url_(std::move(url)), credentials_(std::move(credentials)) {
  while (!url_.empty() && url_.back() == '/') url_.pop_back();
  if (url_.rfind("http://", 0) != 0 && url_.rfind("https://", 0) != 0)
    throw Error(ExitCode::Usage, "--url must start with http:// or https://, not '" + url_ + "'");
  static const bool global = curl_global_init(CURL_GLOBAL_DEFAULT) == CURLE_OK;
  curl_ = global ? curl_easy_init() : nullptr;
  if (!curl_) throw Error(ExitCode::Internal, "libcurl could not be initialised");
}

OrthancClient::~OrthancClient() { curl_easy_cleanup(static_cast<CURL*>(curl_)); }

OrthancClient::Reply OrthancClient::request(const std::string& method, const std::string& path, const std::string* body,
                                            std::FILE* sink) const {
  CURL* c = static_cast<CURL*>(curl_);
  curl_easy_reset(c);
  Reply r;
  const std::string target = url_ + path;
  curl_easy_setopt(c, CURLOPT_URL, target.c_str());
  curl_easy_setopt(c, CURLOPT_NOSIGNAL, 1L);
  curl_easy_setopt(c, CURLOPT_TCP_NODELAY, 1L);
  curl_easy_setopt(c, CURLOPT_CONNECTTIMEOUT, kConnectTimeoutS);
  curl_easy_setopt(c, CURLOPT_TIMEOUT, kRequestTimeoutS);
  if (!credentials_.empty()) {
    curl_easy_setopt(c, CURLOPT_HTTPAUTH, CURLAUTH_BASIC);
    curl_easy_setopt(c, CURLOPT_USERPWD, credentials_.c_str());
  }
  if (method != "GET") curl_easy_setopt(c, CURLOPT_CUSTOMREQUEST, method.c_str());
  if (body) {
    curl_easy_setopt(c, CURLOPT_POSTFIELDS, body->data());
    curl_easy_setopt(c, CURLOPT_POSTFIELDSIZE_LARGE, static_cast<curl_off_t>(body->size()));
  }
  if (sink) {
    curl_easy_setopt(c, CURLOPT_WRITEFUNCTION, to_file);
    curl_easy_setopt(c, CURLOPT_WRITEDATA, sink);
  } else {
    curl_easy_setopt(c, CURLOPT_WRITEFUNCTION, to_string);
    curl_easy_setopt(c, CURLOPT_WRITEDATA, &r.body);
  }
  const CURLcode rc = curl_easy_perform(c);
  if (rc != CURLE_OK) throw Error(ExitCode::InputNotFound, "Orthanc " + method + " " + target + ": " + curl_easy_strerror(rc));
  curl_easy_getinfo(c, CURLINFO_RESPONSE_CODE, &r.status);
  return r;
}

void OrthancClient::check(const std::string& method, const std::string& path, const Reply& r) const {
  if (r.status >= 200 && r.status < 300) return;
  const std::string what = "Orthanc " + method + " " + url_ + path + ": HTTP " + std::to_string(r.status);
  if (r.status == 401 || r.status == 403) throw Error(ExitCode::Usage, what + " (check --credentials)");
  if (r.status == 404) throw Error(ExitCode::InputNotFound, what + " (not found)");
  throw Error(ExitCode::InputInvalid, what + (r.body.empty() ? "" : ": " + r.body.substr(0, 200)));
}

Json OrthancClient::get_json(const std::string& path) const {
  const Reply r = request("GET", path, nullptr, nullptr);
  check("GET", path, r);
  try {
    return parse_json(r.body);
  } catch (const std::exception& e) {
    throw Error(ExitCode::InputInvalid, "Orthanc GET " + url_ + path + ": not JSON: " + e.what());
  }
}

void OrthancClient::download(const std::string& path, const std::string& file) const {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(file.c_str(), "wb"), std::fclose);
  if (!f) throw Error(ExitCode::OutputFailed, file + ": cannot write");
  const Reply r = request("GET", path, nullptr, f.get());
  check("GET", path, r);
}

Json OrthancClient::post_file(const std::string& path, const std::string& file) const {
  const std::string bytes = read_file_or_empty(file);
  if (bytes.empty()) throw Error(ExitCode::InputNotFound, file + ": missing or empty");
  const Reply r = request("POST", path, &bytes, nullptr);
  check("POST", path, r);
  return parse_json(r.body);
}

void OrthancClient::put_text(const std::string& path, const std::string& body) const {
  const Reply r = request("PUT", path, &body, nullptr);
  check("PUT", path, r);
}

std::string OrthancClient::get_text(const std::string& path, bool* found) const {
  const Reply r = request("GET", path, nullptr, nullptr);
  *found = r.status != 404;
  if (!*found) return {};
  check("GET", path, r);
  return r.body;
}

}  // namespace ms::pipeline
