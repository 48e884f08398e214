// SPDX-License-Identifier: GPL-3.0-or-later
#include "mlt/chain_runner.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <functional>
#include <limits>
#include <optional>
#include <utility>

#include "core/math/stopwatch.h"
#include "core/sampling/distribution_1d.h"
#include "mlt/primary_sample_vector.h"

namespace gdmlt::mlt {
namespace {

// Stream identifiers: each purpose gets its own family of PCG streams, so bootstrap samples,
// the independent check and the chains never share random numbers.
constexpr std::uint64_t kBootstrapStreams = 0xB0075;
constexpr std::uint64_t kIndependentStreams = 0x1D3B;
constexpr std::uint64_t kChainStreams = 0xC4A1;

/// Ctrl-C is polled this often inside a chain's share of a round.
constexpr std::uint64_t kCancelPollInterval = 256;

Pcg32 generator(std::uint64_t key) {
    return Pcg32(key, mix_bits(key));
}

/// A splat waiting for the end of its round (float values: accumulation is in double, and a
/// record is 16 bytes, so a round's queue stays small).
struct QueuedSplat {
    std::uint32_t slot;
    float value[3];
};

struct Chain {
    Chain(PrimarySampleVector psv_, Pcg32 control_, std::size_t start)
        : psv(std::move(psv_)), control(control_), start_index(start) {}

    PrimarySampleVector psv;
    Pcg32 control;  // large-step choices and acceptance
    ChainState current, proposal;
    std::uint64_t streak = 0, longest_streak = 0;
    double brightness_sum = 0.0;
    std::uint64_t iterations = 0;
    std::uint64_t round_iterations = 0;  // in the last round (fewer than asked after Ctrl-C)
    std::uint64_t large_proposed = 0, large_accepted = 0, small_proposed = 0, small_accepted = 0;
    std::uint64_t nonfinite = 0;
    ChainCounters counters;
    std::size_t start_index = 0;  // the bootstrap sample it started from
    // Large steps are independent uniform samples of f: their targets refine b (run_chains).
    double large_target_sum = 0.0, large_target_sum2 = 0.0;
    // Splats of the chain part (weights with the bootstrap's b, rescaled once b is final) and
    // of Kelemen's large-step part (independent of b).
    std::vector<QueuedSplat> queue, large_queue;
    std::vector<std::uint32_t> visits;  // density slot of the state after each iteration
    // With batch variance: this round's splats summed per slot (sorted by slot), both parts.
    std::vector<std::pair<std::uint32_t, RgbD>> batch;
};

/// Per slot, what batch means need (ChainRunnerOutput::variance): sum_b x_b^2 (summed over
/// the channels), sum_b n_b x_b, and how many batches splatted into it.
struct BatchSums {
    std::vector<double> squares;
    std::vector<RgbD> weighted;
    std::vector<std::uint32_t> batches;
    double batch_size_squares = 0.0;  // sum_b n_b^2 over every batch, splatting or not
    std::uint64_t batch_count = 0;

    explicit BatchSums(std::size_t slots)
        : squares(slots, 0.0), weighted(slots, RgbD::Zero()), batches(slots, 0) {}
};

/// A chain's round as one batch: its queued splats (the chain part weighted with the
/// bootstrap's b, which differs from the final b by b's error only) summed per slot.
void sum_batch(Chain& chain) {
    chain.batch.clear();
    for (const std::vector<QueuedSplat>* queue : {&chain.queue, &chain.large_queue})
        for (const QueuedSplat& q : *queue)
            chain.batch.emplace_back(q.slot, RgbD(q.value[0], q.value[1], q.value[2]));
    // Stable: equal slots keep queue order, so every sum is the same at any thread count.
    std::stable_sort(chain.batch.begin(), chain.batch.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    std::size_t out = 0;
    for (std::size_t i = 0; i < chain.batch.size(); ++i) {
        if (out > 0 && chain.batch[out - 1].first == chain.batch[i].first)
            chain.batch[out - 1].second += chain.batch[i].second;
        else
            chain.batch[out++] = chain.batch[i];
    }
    chain.batch.resize(out);
}

void add_batch(const Chain& chain, double batch_size, BatchSums& sums) {
    for (const auto& [slot, x] : chain.batch) {
        sums.squares[slot] += x.square().sum();
        sums.weighted[slot] += batch_size * x;
        ++sums.batches[slot];
    }
    sums.batch_size_squares += batch_size * batch_size;
    ++sums.batch_count;
}

void evaluate_state(const ChainTarget& target, SampleStream& stream, ChainState& state,
                    ChainCounters& counters) {
    state.clear();
    target.evaluate(stream, state, counters);
    if (state.nonfinite || !std::isfinite(state.target) || !(state.target >= 0.0)) {
        // Dropped and counted; a zero-target state is never splatted (pbrt-v4 once produced NaN
        // here by dividing by a zero luminance).
        state.clear();
        state.nonfinite = true;
        return;
    }
    if (state.target == 0.0) state.splats.clear();
}

/// An independent sample with the given generator, drawn exactly as a chain's first (large)
/// step draws it, so that a chain can start from it by replaying the generator.
double independent_target(const ChainTarget& target, const ChainRunnerSettings& settings,
                          std::uint64_t key, ChainState& state, ChainCounters& counters) {
    PrimarySampleVector psv(settings.mutation, generator(key), settings.image_width,
                            settings.image_height);
    psv.start_iteration(true);
    evaluate_state(target, psv, state, counters);
    return state.nonfinite ? -1.0 : state.target;
}

struct MeanEstimate {
    double mean = 0.0, standard_error = 0.0;
    std::uint64_t nonzero = 0;
};

/// Mean and standard error of the mean of n samples, from their sum and sum of squares.
MeanEstimate mean_from_sums(double sum, double sum2, double n) {
    MeanEstimate m;
    if (n == 0) return m;
    m.mean = sum / n;
    m.standard_error = n > 1 ? std::sqrt(std::max(0.0, sum2 / n - m.mean * m.mean) / (n - 1)) : 0.0;
    return m;
}

MeanEstimate mean_of(const std::vector<double>& values) {
    double sum = 0.0, sum2 = 0.0;
    std::uint64_t nonzero = 0;
    for (double v : values) {  // in index order: deterministic
        sum += v;
        sum2 += v * v;
        if (v > 0.0) ++nonzero;
    }
    MeanEstimate m = mean_from_sums(sum, sum2, static_cast<double>(values.size()));
    m.nonzero = nonzero;
    return m;
}

/// The independent samples' contributions, summed per slot: each sample is uniform over primary
/// sample space, so sums / count estimate every slot's integral without a chain.
struct SplatSums {
    std::vector<RgbD> sums;
    std::vector<std::vector<Splat>> batch;  // per sample of the current batch, merged in order
};

/// Targets of independent samples [first, first + count) of stream family `family`, appended
/// to `values` in index order; non-finite ones count as 0 and are counted. With `splats`, their
/// splats are added to splats->sums in index order (deterministic at any thread count).
/// Evaluated in batches, between which `stop` is asked (a huge bootstrap must not outlast
/// Ctrl-C or the time budget) and after each of which `after_batch` is called. Returns how many
/// were appended (fewer than `count` only when stopped).
/// Independent samples are evaluated in batches of this many (~0.1 s of GDMLT proposals on 2
/// cores); stop conditions are checked between batches.
constexpr std::size_t kIndependentBatch = 8192;

std::size_t append_independent_targets(const ChainTarget& target,
                                       const ChainRunnerSettings& settings, std::uint64_t family,
                                       std::size_t first, std::size_t count,
                                       std::vector<double>& values,
                                       tbb::enumerable_thread_specific<ChainCounters>& counters,
                                       std::uint64_t& nonfinite, const std::function<bool()>& stop,
                                       SplatSums* splats = nullptr,
                                       const std::function<void()>& after_batch = {}) {
    constexpr std::size_t kBatch = kIndependentBatch;
    const std::size_t base = values.size();
    values.resize(base + count, 0.0);
    if (splats) splats->batch.resize(std::min(count, kBatch));
    tbb::enumerable_thread_specific<ChainState> states;
    std::size_t done = 0;
    while (done < count && !stop()) {
        const std::size_t batch_end = std::min(count, done + kBatch);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(done, batch_end, 256),
                          [&](const tbb::blocked_range<std::size_t>& r) {
                              ChainCounters& local = counters.local();
                              ChainState& state = states.local();
                              for (std::size_t i = r.begin(); i != r.end(); ++i) {
                                  values[base + i] = independent_target(
                                      target, settings,
                                      derive_stream(settings.seed, family, first + i), state,
                                      local);
                                  if (splats) splats->batch[i - done] = state.splats;
                              }
                          });
        if (splats)
            for (std::size_t i = done; i < batch_end; ++i)
                for (const Splat& s : splats->batch[i - done])
                    splats->sums[s.slot] += s.value.cast<double>();
        done = batch_end;
        if (after_batch) after_batch();
    }
    values.resize(base + done);
    for (std::size_t i = base; i < values.size(); ++i)
        if (values[i] < 0.0) {
            values[i] = 0.0;
            ++nonfinite;
        }
    return done;
}

void queue_splats(std::vector<QueuedSplat>& queue, const ChainState& state, double weight) {
    if (!(weight > 0.0)) return;
    for (const Splat& s : state.splats) {
        const Rgb v = s.value * static_cast<float>(weight);
        queue.push_back({s.slot, {v[0], v[1], v[2]}});
    }
}

/// Adds a chain's queued splats of a round to `accumulated` (in queue order: called in chain
/// order, the sums are the same at any thread count) and empties the queue.
void merge_queue(std::vector<QueuedSplat>& queue, std::vector<RgbD>& accumulated) {
    for (const QueuedSplat& q : queue)
        for (int k = 0; k < 3; ++k) accumulated[q.slot][k] += static_cast<double>(q.value[k]);
    queue.clear();
}

/// Advances one chain by up to `mutations` iterations, queueing its splats.
void run_chain(Chain& chain, const ChainTarget& target, const ChainRunnerSettings& settings,
               double b, std::uint64_t mutations, bool track_density,
               const std::atomic<bool>* cancel) {
    const double p_large = settings.mutation.p_large;
    for (std::uint64_t m = 0; m < mutations; ++m) {
        if (m % kCancelPollInterval == kCancelPollInterval - 1 && cancel &&
            cancel->load(std::memory_order_relaxed))
            return;
        const bool large = chain.control.next_double() < p_large;
        chain.psv.start_iteration(large);
        evaluate_state(target, chain.psv, chain.proposal, chain.counters);
        if (chain.proposal.nonfinite) ++chain.nonfinite;
        const ChainState& proposal = chain.proposal;
        const ChainState& current = chain.current;
        // Symmetric proposals: a = min(1, f(y) / f(x)) (Metropolis-Hastings).
        const double accept =
            current.target > 0.0 ? std::min(1.0, proposal.target / current.target) : 1.0;

        // Splat both states with expected-value weights (Veach 1997, sec. 11.5), optionally
        // MIS-combined with the large steps as an independent estimator (Kelemen et al. 2002):
        // proposal (a + [large]) g(y) / (f(y)/b + p_L), current (1 - a) g(x) / (f(x)/b + p_L).
        // The a and (1 - a) terms are the chain's: b g / f times the MIS weight
        // (f/b) / (f/b + p_L). Any b in the MIS weights keeps them summing to 1, so the chain's
        // terms scale with b exactly and run_chains rescales them to the final b; the [large]
        // term is the uniform estimator g / p_L times its MIS weight and does not involve b.
        if (settings.kelemen_weights) {
            if (proposal.target > 0.0) {
                const double mis = 1.0 / (proposal.target / b + p_large);
                queue_splats(chain.queue, proposal, accept * mis);
                if (large) queue_splats(chain.large_queue, proposal, mis);
            }
            if (current.target > 0.0 && accept < 1.0)
                queue_splats(chain.queue, current, (1.0 - accept) / (current.target / b + p_large));
        } else {
            if (proposal.target > 0.0)
                queue_splats(chain.queue, proposal, accept * b / proposal.target);
            if (current.target > 0.0 && accept < 1.0)
                queue_splats(chain.queue, current, (1.0 - accept) * b / current.target);
        }
        if (large) {
            const double f = proposal.nonfinite ? 0.0 : proposal.target;
            chain.large_target_sum += f;
            chain.large_target_sum2 += f * f;
        }

        (large ? chain.large_proposed : chain.small_proposed) += 1;
        if (chain.control.next_double() < accept) {
            chain.psv.accept();
            std::swap(chain.current, chain.proposal);  // keeps both splat lists' capacity
            (large ? chain.large_accepted : chain.small_accepted) += 1;
            chain.streak = 0;
        } else {
            chain.psv.reject();
            chain.longest_streak = std::max(chain.longest_streak, ++chain.streak);
        }
        chain.brightness_sum += chain.current.target;
        if (track_density && chain.current.density_slot >= 0)
            chain.visits.push_back(static_cast<std::uint32_t>(chain.current.density_slot));
        ++chain.iterations;
    }
}

}  // namespace

ChainRunnerOutput run_chains(const ChainTarget& target, const ChainRunnerSettings& settings,
                             const std::atomic<bool>* cancel,
                             const std::function<void(double, double)>& progress) {
    const Clock::time_point start = Clock::now();
    auto cancelled = [&] { return cancel && cancel->load(std::memory_order_relaxed); };
    const bool timed = settings.time_budget_s > 0.0;
    const int chain_count = std::max(settings.chains, 1);

    ChainRunnerOutput out;
    ChainStats& stats = out.stats;
    stats.chains = chain_count;
    std::vector<RgbD> accumulated(target.slot_count(), RgbD::Zero());  // the chain part
    std::vector<RgbD> accumulated_large;  // Kelemen's large-step part, when weighted so
    std::vector<std::uint64_t> visits(target.density_slot_count(), 0);

    // 1. Bootstrap (Kelemen et al. 2002, sec. 5): b from independent samples; chain start states
    //    resampled proportionally to f, which removes start-up bias.
    tbb::enumerable_thread_specific<ChainCounters> counters;
    const std::size_t initial =
        std::max<std::size_t>(static_cast<std::size_t>(settings.bootstrap_samples),
                              10 * static_cast<std::size_t>(chain_count));
    // Ctrl-C or the whole time budget stops the bootstrap between batches (then no chain
    // runs, and the estimate is the bootstrap samples' mean).
    const auto stop = [&] {
        return cancelled() || (timed && seconds_since(start) >= settings.time_budget_s);
    };
    // The bootstrap's splats too: should the run stop before any chain has run, their mean is
    // the estimate (an unbiased whole image, where the chains would have left nothing).
    SplatSums bootstrap_splats;
    bootstrap_splats.sums.assign(target.slot_count(), RgbD::Zero());
    const auto bootstrap_progress = [&] {
        if (progress) progress(0.0, seconds_since(start));
    };
    std::vector<double> bootstrap;
    // With a time budget the bootstrap's share of it bounds the initial samples too, once there
    // are 10 per chain to resample starts from: bidirectional GDMLT with shifted light tracing
    // evaluates ~15k states/s on caustic_glass_light, so 100000 samples (and the check of b
    // below) took 9 of 16 s. b loses nothing: every large step refines it.
    std::size_t initial_done = 0;
    const std::size_t minimum = 10 * static_cast<std::size_t>(chain_count);
    const double bootstrap_share_s = settings.bootstrap_time_fraction * settings.time_budget_s;
    const auto initial_stop = [&] {
        return stop() ||
               (timed && initial_done >= minimum && seconds_since(start) >= bootstrap_share_s);
    };
    append_independent_targets(target, settings, kBootstrapStreams, 0, initial, bootstrap, counters,
                               stats.nonfinite_dropped, initial_stop, &bootstrap_splats, [&] {
                                   initial_done += kIndependentBatch;
                                   bootstrap_progress();
                               });
    const double batch_s = seconds_since(start);
    MeanEstimate b_estimate = mean_of(bootstrap);
    // Every pixel's brightness is b's: grow the bootstrap until b is as precise as asked. With
    // a time budget, only while the next batch fits into the bootstrap's share of it: these
    // samples are not splatted, and at short budgets the chains need the time more.
    while (settings.bootstrap_relative_error > 0.0 &&
           b_estimate.standard_error > settings.bootstrap_relative_error * b_estimate.mean &&
           bootstrap.size() < 16 * initial && !cancelled() &&
           !(timed && seconds_since(start) + batch_s >
                          settings.bootstrap_time_fraction * settings.time_budget_s)) {
        append_independent_targets(target, settings, kBootstrapStreams, bootstrap.size(), initial,
                                   bootstrap, counters, stats.nonfinite_dropped, stop,
                                   &bootstrap_splats, bootstrap_progress);
        b_estimate = mean_of(bootstrap);
    }
    stats.b = stats.b_bootstrap = b_estimate.mean;
    stats.b_standard_error = stats.b_bootstrap_standard_error = b_estimate.standard_error;
    stats.bootstrap_samples = stats.b_samples = bootstrap.size();
    stats.bootstrap_nonzero = b_estimate.nonzero;
    {
        std::vector<double> check;
        std::uint64_t ignored = 0;  // the check's failures are not the render's
        // A check, not used: with a time budget it may take a quarter of the bootstrap's time.
        const double check_until_s = seconds_since(start) * 1.25;
        bool checked_a_batch = false;
        append_independent_targets(
            target, settings, kIndependentStreams, 0,
            std::max<std::size_t>(bootstrap.size() / 4, 1), check, counters, ignored,
            [&] {
                return stop() ||
                       (timed && checked_a_batch && seconds_since(start) >= check_until_s);
            },
            nullptr, [&] { checked_a_batch = true; });
        const MeanEstimate independent = mean_of(check);
        stats.b_independent = independent.mean;
        stats.b_independent_standard_error = independent.standard_error;
    }
    stats.bootstrap_s = seconds_since(start);
    auto finish = [&] {
        for (const ChainCounters& c : counters) {
            stats.counters += c.paths;
            stats.shifts += c.shifts;
        }
        stats.interrupted = cancelled();
        stats.total_s = seconds_since(start);
    };
    if (!(stats.b > 0.0)) {
        // Every bootstrap sample had a zero target: nothing for the chains to find.
        out.estimate = std::move(accumulated);
        out.density.assign(visits.size(), 0.0);
        finish();
        return out;
    }

    std::vector<float> weights(bootstrap.begin(), bootstrap.end());
    const Distribution1D start_states(weights);
    std::vector<Chain> chains;
    chains.reserve(static_cast<std::size_t>(chain_count));
    for (int c = 0; c < chain_count; ++c) {
        Pcg32 control =
            generator(derive_stream(settings.seed, kChainStreams, static_cast<std::uint64_t>(c)));
        const std::size_t index = start_states.sample(control.next_float());
        const std::uint64_t key = derive_stream(settings.seed, kBootstrapStreams, index);
        chains.emplace_back(PrimarySampleVector(settings.mutation, generator(key),
                                                settings.image_width, settings.image_height),
                            control, index);
    }
    // Replay each start state (parallel: each is one evaluation).
    tbb::parallel_for(0, chain_count, [&](int c) {
        Chain& chain = chains[static_cast<std::size_t>(c)];
        chain.psv.start_iteration(true);
        evaluate_state(target, chain.psv, chain.current, chain.counters);
        chain.psv.accept();
    });
    for (const Chain& chain : chains) {
        // Mitsuba's guard: a start state that does not reproduce its bootstrap value means the
        // target is not a deterministic function of its primary samples.
        const double recorded = bootstrap[chain.start_index];
        if (std::abs(chain.current.target - recorded) > 1e-6 * recorded) ++stats.replay_mismatches;
    }

    // 2. Chains, in rounds: a round advances every chain by the same number of mutations, so
    //    time budgets act between rounds. With a mutation budget the rounds are fixed and the
    //    queues are merged in chain order: the result is fixed, bit for bit.
    const Clock::time_point chains_start = Clock::now();
    const std::uint64_t per_chain_budget = timed && settings.mutations == 0
                                               ? std::numeric_limits<std::uint64_t>::max() / 4
                                               : (std::max<std::uint64_t>(settings.mutations, 1) +
                                                  static_cast<std::uint64_t>(chain_count) - 1) /
                                                     static_cast<std::uint64_t>(chain_count);
    const bool track_density = !visits.empty();
    std::optional<BatchSums> batch_sums;
    if (settings.batch_variance) batch_sums.emplace(accumulated.size());
    std::uint64_t per_chain_done = 0;
    std::uint64_t round_size = timed ? 64 : std::min<std::uint64_t>(per_chain_budget, 1024);
    while (per_chain_done < per_chain_budget && !cancelled()) {
        if (timed && settings.time_budget_s - seconds_since(start) <= 0.0) break;
        const std::uint64_t this_round = std::min(round_size, per_chain_budget - per_chain_done);
        const Clock::time_point round_start = Clock::now();
        tbb::parallel_for(0, chain_count, [&](int c) {
            Chain& chain = chains[static_cast<std::size_t>(c)];
            const std::uint64_t before = chain.iterations;
            run_chain(chain, target, settings, stats.b_bootstrap, this_round, track_density,
                      cancel);
            chain.round_iterations = chain.iterations - before;
            if (batch_sums) sum_batch(chain);
        });
        for (Chain& chain : chains) {
            if (batch_sums && chain.round_iterations > 0)
                add_batch(chain, static_cast<double>(chain.round_iterations), *batch_sums);
            merge_queue(chain.queue, accumulated);
            if (!chain.large_queue.empty() && accumulated_large.empty())
                accumulated_large.assign(accumulated.size(), RgbD::Zero());
            merge_queue(chain.large_queue, accumulated_large);
            for (std::uint32_t v : chain.visits) ++visits[v];
            chain.visits.clear();
        }
        per_chain_done += this_round;
        if (timed) {
            // Rounds of about half a second, never past the budget.
            const double per_mutation =
                seconds_since(round_start) / static_cast<double>(this_round);
            const double remaining = settings.time_budget_s - seconds_since(start);
            const double goal = std::min(0.5, std::max(remaining, 0.0));
            round_size = std::clamp<std::uint64_t>(
                static_cast<std::uint64_t>(goal / std::max(per_mutation, 1e-9)), 1, 1 << 16);
        }
        if (progress) {
            const double fraction =
                timed ? seconds_since(start) / settings.time_budget_s
                      : static_cast<double>(per_chain_done) / static_cast<double>(per_chain_budget);
            progress(std::min(fraction, 1.0), seconds_since(start));
        }
    }
    stats.chains_s = seconds_since(chains_start);

    // 3. Statistics, and the estimate: sum of splats / N.
    std::vector<double> longest, brightness;
    for (const Chain& c : chains) {
        stats.mutations += c.iterations;
        stats.large_proposed += c.large_proposed;
        stats.large_accepted += c.large_accepted;
        stats.small_proposed += c.small_proposed;
        stats.small_accepted += c.small_accepted;
        stats.nonfinite_dropped += c.nonfinite;
        stats.longest_rejection_streak = std::max(stats.longest_rejection_streak, c.longest_streak);
        stats.counters += c.counters.paths;
        stats.shifts += c.counters.shifts;
        longest.push_back(static_cast<double>(c.longest_streak));
        if (c.iterations > 0)
            brightness.push_back(c.brightness_sum / static_cast<double>(c.iterations));
    }
    if (!longest.empty()) {
        std::nth_element(longest.begin(),
                         longest.begin() + static_cast<std::ptrdiff_t>(longest.size() / 2),
                         longest.end());
        stats.median_longest_rejection_streak = longest[longest.size() / 2];
    }
    if (!brightness.empty()) {
        const MeanEstimate m = mean_of(brightness);
        stats.chain_brightness_mean = m.mean;
        const double sd = m.standard_error * std::sqrt(static_cast<double>(brightness.size()));
        stats.chain_brightness_relative_spread = m.mean > 0.0 ? sd / m.mean : 0.0;
    }
    // The final b: the bootstrap's samples and every large step's (both uniform and
    // independent; a chain's large steps outnumber the bootstrap at any budget beyond a few
    // seconds). b sets the whole image's brightness: PSSMLT's image means at 16 s were 1-7%
    // off with b from 100k bootstrap samples alone on caustic_glass_light.
    {
        double sum = 0.0, sum2 = 0.0;
        for (double v : bootstrap) {
            sum += v;
            sum2 += v * v;
        }
        for (const Chain& c : chains) {  // chain order: deterministic
            sum += c.large_target_sum;
            sum2 += c.large_target_sum2;
        }
        stats.b_samples = bootstrap.size() + stats.large_proposed;
        const MeanEstimate b = mean_from_sums(sum, sum2, static_cast<double>(stats.b_samples));
        stats.b = b.mean;
        stats.b_standard_error = b.standard_error;
    }
    if (batch_sums && stats.mutations > 0 && batch_sums->batch_count > 1) {
        // Per channel sum_b (x_b - n_b S)^2 = sum x^2 - 2 S sum n x + S^2 sum n^2 with
        // S = sum x / N, before the rescaling below (x holds both parts as splatted).
        const double n = static_cast<double>(stats.mutations);
        const double batches = static_cast<double>(batch_sums->batch_count);
        const double scale = batches / (batches - 1.0) / (n * n) / 3.0;
        out.variance.assign(accumulated.size(), std::numeric_limits<double>::infinity());
        for (std::size_t i = 0; i < accumulated.size(); ++i) {
            if (batch_sums->batches[i] < 2) continue;
            const RgbD sum = accumulated_large.empty()
                                 ? accumulated[i]
                                 : RgbD(accumulated[i] + accumulated_large[i]);
            const RgbD mean = sum / n;
            const double deviations = batch_sums->squares[i] -
                                      2.0 * (mean * batch_sums->weighted[i]).sum() +
                                      mean.square().sum() * batch_sums->batch_size_squares;
            out.variance[i] = std::max(deviations, 0.0) * scale;
        }
    }
    if (stats.mutations > 0) {
        const double scale = 1.0 / static_cast<double>(stats.mutations);
        const double chain_scale = scale * stats.b / stats.b_bootstrap;
        for (RgbD& v : accumulated) v *= chain_scale;
        for (std::size_t i = 0; i < accumulated_large.size(); ++i)
            accumulated[i] += accumulated_large[i] * scale;
    } else if (!bootstrap.empty()) {
        // Stopped (Ctrl-C, time budget) before any chain ran: the bootstrap's samples are
        // independent and uniform, so their mean is an unbiased estimate of every slot.
        stats.bootstrap_estimate = true;
        const double scale = 1.0 / static_cast<double>(bootstrap.size());
        for (std::size_t i = 0; i < accumulated.size(); ++i)
            accumulated[i] = bootstrap_splats.sums[i] * scale;
    }
    for (const Chain& c : chains) out.final_density_slots.push_back(c.current.density_slot);
    out.estimate = std::move(accumulated);
    out.density.assign(visits.size(), 0.0);
    std::uint64_t total_visits = 0;
    for (std::uint64_t v : visits) total_visits += v;
    if (total_visits > 0)
        for (std::size_t i = 0; i < visits.size(); ++i)
            out.density[i] = static_cast<double>(visits[i]) / static_cast<double>(total_visits);
    finish();
    return out;
}

}  // namespace gdmlt::mlt
