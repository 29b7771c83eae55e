// Errors and step status: fallible calls return gf::Result; no exception crosses the API.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <variant>

namespace gf {

/// Why a call failed: one line naming the file, the line or field, and the reason.
struct Error {
  std::string message;
};

/// Either a value or an Error. Check ok() before value(); value() on an error aborts through
/// the assertion handler.
template <class T>
class [[nodiscard]] Result {
 public:
  Result(T value) : m_v(std::move(value)) {}      // NOLINT(implicit)
  Result(Error error) : m_v(std::move(error)) {}  // NOLINT(implicit)
  /// True when the call succeeded.
  bool ok() const { return m_v.index() == 0; }
  explicit operator bool() const { return ok(); }
  /// The value; only valid when ok().
  T& value() & { return std::get<0>(m_v); }
  const T& value() const& { return std::get<0>(m_v); }
  T&& value() && { return std::get<0>(std::move(m_v)); }
  /// The error; only valid when !ok().
  const Error& error() const { return std::get<1>(m_v); }

 private:
  std::variant<T, Error> m_v;
};

/// Result of a call that returns nothing on success.
template <>
class [[nodiscard]] Result<void> {
 public:
  Result() = default;
  Result(Error error) : m_error(std::move(error)), m_failed(true) {}  // NOLINT
  bool ok() const { return !m_failed; }
  explicit operator bool() const { return ok(); }
  const Error& error() const { return m_error; }

 private:
  Error m_error;
  bool m_failed = false;
};

/// Builds an Error from pieces, e.g. fail("bar.msh:12: element 7: ", "zero volume").
template <class... Args>
Error fail(const Args&... parts) {
  std::string s;
  (s += ... += std::string(parts));
  return Error{std::move(s)};
}

/// Called when a GF_ASSERT fails. The default prints the message and aborts; tests install a
/// handler that turns it into a test failure, engines one that logs and breaks.
using AssertHandler = void (*)(const char* condition, const char* message, const char* file,
                               int line);
/// Replaces the assertion handler (nullptr restores the default); returns the previous one.
AssertHandler setAssertHandler(AssertHandler handler);
namespace detail {
void assertFailed(const char* condition, const char* message, const char* file, int line);
}  // namespace detail

/// Flags a step raises; several may be set at once.
enum StepFlag : uint32_t {
  kStepOk = 0,
  kStepNotConverged = 1u << 0,  ///< Newton or the linear solver stopped at its iteration cap.
  /// A NaN/Inf appeared or the elastic energy blew up (over 1e6 x Young's modulus x volume: a
  /// diverged solve); the body was rolled back to its last state and the message says which.
  kStepNanContained = 1u << 1,
  kStepInvalidInput = 1u << 2,      ///< The call was rejected (e.g. dt <= 0); nothing changed.
  kStepLineSearchFailed = 1u << 3,  ///< Newton's line search hit its minimum step.
  /// A node's path over the step would have passed through a thin box or a small sphere
  /// collider (or the collider through it): contact was taken at the face the path entered,
  /// which stopped it there. Information, not an error.
  kStepContactSwept = 1u << 4,
};

/// What World::step reports. Ignoring it is a compile warning.
struct [[nodiscard]] StepStatus {
  uint32_t flags = kStepOk;
  int newtonIterations = 0;  ///< Summed over bodies and substeps.
  int linearIterations = 0;  ///< Summed over bodies and substeps (0 for the direct solver).
  double residual = 0;       ///< Worst final relative linear residual of the step.
  std::string message;       ///< Human-readable reason when flags != kStepOk.
  bool ok() const { return flags == kStepOk; }
  bool has(StepFlag f) const { return (flags & f) != 0; }
};

}  // namespace gf

/// Checks an internal invariant in every build type; a failure goes to the AssertHandler.
#define GF_ASSERT(cond, msg)                                                 \
  do {                                                                       \
    if (!(cond)) ::gf::detail::assertFailed(#cond, msg, __FILE__, __LINE__); \
  } while (0)

/// Heavy checks, compiled only with -DGF_VALIDATE=ON.
#if defined(GF_VALIDATE_ENABLED)
#define GF_VALIDATE(cond, msg) GF_ASSERT(cond, msg)
#else
#define GF_VALIDATE(cond, msg) \
  do {                         \
  } while (0)
#endif
