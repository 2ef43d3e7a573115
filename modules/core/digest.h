// SHA-256 (FIPS 180-4) for the provenance hashes in MandiSym's outputs
// (pixel data, --mask files, batch inputs), computed by OpenSSL's EVP
// interface (libssl-dev), which uses the CPU's SHA extensions where present.
#pragma once

#include <cstddef>
#include <memory>
#include <string>

struct evp_md_ctx_st;

namespace ms {

// Streaming SHA-256 hasher.
//   ms::Sha256 h; h.update(p, n); ...; std::string hex = h.hex_digest();
class Sha256 {
 public:
  Sha256();
  ~Sha256();
  Sha256(const Sha256&) = delete;
  Sha256& operator=(const Sha256&) = delete;

  // Takes n bytes at data (data may be null when n == 0) and feeds them to
  // the hash. Throws std::logic_error if called after hex_digest().
  void update(const void* data, size_t n);

  // Finalises the hash and returns the digest as 64 lowercase hex
  // characters. Further calls return the same digest.
  std::string hex_digest();

 private:
  struct FreeContext {
    void operator()(evp_md_ctx_st* c) const;
  };
  std::unique_ptr<evp_md_ctx_st, FreeContext> ctx_;
  std::string digest_;
};

// Takes n bytes at data; returns their SHA-256 as 64 lowercase hex chars.
std::string sha256_hex(const void* data, size_t n);

}  // namespace ms
