// A minimal Orthanc REST client (libcurl): what `mandisym orthanc` needs,
// nothing else (docs/pacs.md). Every failure throws ms::Error naming the
// request: InputNotFound when the server cannot be reached or answers 404,
// Usage on 401/403 (wrong credentials), InputInvalid otherwise.
#pragma once

#include <string>

#include "core/json_text.h"

namespace ms::pipeline {

class OrthancClient {
 public:
  // url: "http://host:port" (a trailing slash is dropped); credentials:
  // "user:password" for HTTP basic authentication, or empty.
  OrthancClient(std::string url, std::string credentials);
  OrthancClient(const OrthancClient&) = delete;
  OrthancClient& operator=(const OrthancClient&) = delete;
  ~OrthancClient();

  Json get_json(const std::string& path) const;
  // The body of a GET (e.g. /instances/{id}/file) written to a file.
  void download(const std::string& path, const std::string& file) const;
  // POST of a file's bytes (e.g. a DICOM file to /instances); the JSON answer.
  Json post_file(const std::string& path, const std::string& file) const;
  // PUT of a text body (e.g. metadata).
  void put_text(const std::string& path, const std::string& body) const;
  // GET of a text body; empty with found = false on 404.
  std::string get_text(const std::string& path, bool* found) const;

  const std::string& url() const { return url_; }

 private:
  struct Reply {
    long status = 0;
    std::string body;
  };
  Reply request(const std::string& method, const std::string& path, const std::string* body, std::FILE* sink) const;
  void check(const std::string& method, const std::string& path, const Reply& r) const;

  std::string url_, credentials_;
  void* curl_ = nullptr;  // CURL*
};

}  // namespace ms::pipeline
