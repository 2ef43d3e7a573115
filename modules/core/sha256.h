// SHA-256 (FIPS 180-4), dependency-free. Used for input/output provenance
// hashes in MandiSym reports.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace ms {

// Streaming SHA-256 hasher.
//   ms::Sha256 h; h.update(p, n); ...; std::string hex = h.hex_digest();
class Sha256 {
 public:
  Sha256();

  // Takes n bytes at data (data may be null when n == 0) and feeds them to
  // the hash. Throws std::logic_error if called after hex_digest().
  void update(const void* data, size_t n);

  // Finalises the hash and returns the digest as 64 lowercase hex
  // characters. Further calls return the same digest.
  std::string hex_digest();

 private:
  void process_block(const uint8_t* block);

  uint32_t state_[8];
  uint8_t buffer_[64];
  size_t buffered_ = 0;
  uint64_t total_bytes_ = 0;
  bool finalised_ = false;
  std::string digest_;
};

// Takes n bytes at data; returns their SHA-256 as 64 lowercase hex chars.
std::string sha256_hex(const void* data, size_t n);

}  // namespace ms
