#pragma once
#include <cstddef>
#include <cstdint>

namespace lw::hal {

/// Page store on NOR flash reserved for the application's persistent state. Erased bytes read
/// 0xFF; programming can only clear bits. Blocking (erase: milliseconds); not ISR-safe. A power
/// loss during Erase or Program may leave the page partially erased or programmed.
class FlashPages {
 public:
  size_t PageSize() { return DoPageSize(); }
  size_t PageCount() { return DoPageCount(); }
  bool Erase(size_t page) { return DoErase(page); }
  bool Program(size_t page, size_t offset, const uint8_t* data, size_t len) { return DoProgram(page, offset, data, len); }
  bool Read(size_t page, size_t offset, uint8_t* data, size_t len) { return DoRead(page, offset, data, len); }

 protected:
  ~FlashPages() = default;

 private:
  virtual size_t DoPageSize() = 0;
  virtual size_t DoPageCount() = 0;
  virtual bool DoErase(size_t page) = 0;
  virtual bool DoProgram(size_t page, size_t offset, const uint8_t* data, size_t len) = 0;
  virtual bool DoRead(size_t page, size_t offset, uint8_t* data, size_t len) = 0;
};

}  // namespace lw::hal
