// A mutual interaction of any type behind one value type: what an
// interaction's descriptor builds (registry.hpp) and the run evaluates.
#pragma once

#include <lgvi/interaction.hpp>

#include <memory>
#include <optional>
#include <type_traits>
#include <utility>

namespace lgvi::app {

/// A mutual interaction of any type (a MutualInteraction), held by value:
/// copies are deep, as the held interaction's own (each has its own
/// workspace, e.g. neighbour lists, and shares the model: interaction.hpp),
/// so copies may run on different threads. Empty: no interaction.
class AnyMutualInteraction {
 public:
  AnyMutualInteraction() = default;
  template <MutualInteraction M>
    requires(!std::is_same_v<std::remove_cvref_t<M>, AnyMutualInteraction>)
  AnyMutualInteraction(M m) : held_(std::make_unique<Model<M>>(std::move(m))) {}  // NOLINT(google-explicit-constructor)
  AnyMutualInteraction(const AnyMutualInteraction& o) : held_(o.held_ ? o.held_->clone() : nullptr) {}
  AnyMutualInteraction(AnyMutualInteraction&&) noexcept = default;
  AnyMutualInteraction& operator=(const AnyMutualInteraction& o) {
    if (this != &o) held_ = o.held_ ? o.held_->clone() : nullptr;
    return *this;
  }
  AnyMutualInteraction& operator=(AnyMutualInteraction&&) noexcept = default;
  ~AnyMutualInteraction() = default;

  void add(const SystemState& s, SystemEvaluation& e) {
    if (held_) held_->add(s, e);
  }
  bool empty() const { return !held_; }
  /// The held interaction's molecular virial at `s` (PairInteraction::virial),
  /// if it has one: nullopt for none, or one without (long-range gravity).
  std::optional<double> virial(const SystemState& s) { return held_ ? held_->virial(s) : std::nullopt; }
  /// The held interaction if it is an M, else null.
  template <class M>
  const M* get() const {
    const auto* model = dynamic_cast<const Model<M>*>(held_.get());
    return model ? &model->m : nullptr;
  }

 private:
  struct Concept {
    virtual ~Concept() = default;
    virtual void add(const SystemState& s, SystemEvaluation& e) = 0;
    virtual std::optional<double> virial(const SystemState& s) = 0;
    virtual std::unique_ptr<Concept> clone() const = 0;
  };
  template <class M>
  struct Model final : Concept {
    explicit Model(M held) : m(std::move(held)) {}
    void add(const SystemState& s, SystemEvaluation& e) override { m.add(s, e); }
    std::optional<double> virial(const SystemState& s) override {
      if constexpr (requires { m.virial(s); })
        return m.virial(s);
      else
        return std::nullopt;
    }
    std::unique_ptr<Concept> clone() const override { return std::make_unique<Model>(m); }
    M m;
  };
  std::unique_ptr<Concept> held_;
};

}  // namespace lgvi::app
