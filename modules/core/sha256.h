// SHA-256 (FIPS 180-4), dependency-free. Used for input/output provenance
// hashes in MandiSym reports. On x86-64 CPUs with the SHA extensions (Intel
// since Ice Lake / Goldmont, AMD since Zen) the compression function runs on
// them (~5x the portable code); the choice is made once, at run time.
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
  // Compresses n consecutive 64-byte blocks into state_.
  void process_blocks(const uint8_t* blocks, size_t n);

  uint32_t state_[8];
  uint8_t buffer_[64];
  size_t buffered_ = 0;
  uint64_t total_bytes_ = 0;
  bool finalised_ = false;
  std::string digest_;
};

// Takes n bytes at data; returns their SHA-256 as 64 lowercase hex chars.
std::string sha256_hex(const void* data, size_t n);

// True when this CPU has the SHA extensions and they are in use.
bool sha256_uses_cpu_extensions();

// Takes false to make every Sha256 use the portable code from now on, true to
// go back to the CPU extensions where the CPU has them (tests compare both).
void sha256_allow_cpu_extensions(bool allow);

}  // namespace ms
