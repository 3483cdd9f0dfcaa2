//! Learning costs online (pure): a few costs fitted to what each frame measured, with a
//! calibration as the prior.
//!
//! The machine changes in two ways. What things cost relative to each other (a triangle
//! against a point, the fixed part against the rest) is a property of the renderer and
//! changes rarely; how fast the machine runs changes within a second (a CPU changing
//! clock, another process waking). [`CostFilter`] estimates both at once, and tells them
//! apart by how the regressors vary. [`PriorRegression`] is the plain exponentially
//! weighted least squares, regularised toward a prior, for a quantity that is measured
//! directly. Learning happens after a frame from what was measured of it and never feeds
//! back within the frame: the budget predicts with the current estimates and this
//! frame's own counts.

/// Exponentially weighted least squares regularised toward a prior: the `θ` that minimises
/// `Σᵢ wᵢ λ^(ageᵢ) (yᵢ − θ·xᵢ)² + Σⱼ δⱼ (θⱼ − θ⁰ⱼ)²`, where the strength `δⱼ` of the prior
/// is [`PriorRegression::prior_frames`] frames' worth of regressor `j`'s recent excitation
/// (its weighted mean square). So the prior always weighs the same against the data,
/// whatever the units, and a regressor that stays 0 keeps its prior exactly.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct PriorRegression<const N: usize> {
    prior: [f64; N],
    /// Each parameter stays within these bounds (after the solve).
    lower: [f64; N],
    upper: [f64; N],
    /// How many frames of data the prior is worth. Default: `0.1`.
    pub prior_frames: f64,
    /// Time constant of the forgetting, seconds.
    pub time_constant: f64,
    gram: [[f64; N]; N],
    moment: [f64; N],
    /// Weighted mean square of each regressor, and the total weight it averages.
    mean_square: [f64; N],
    weight: f64,
    theta: [f64; N],
}

impl<const N: usize> PriorRegression<N> {
    /// A regression starting at (and regularised toward) `prior`, each parameter kept
    /// within `lower..=upper`, forgetting with `time_constant` seconds.
    pub(crate) fn new(
        prior: [f64; N],
        lower: [f64; N],
        upper: [f64; N],
        time_constant: f64,
    ) -> Self {
        let theta = core::array::from_fn(|j| prior[j].clamp(lower[j], upper[j]));
        Self {
            prior: theta,
            lower,
            upper,
            prior_frames: 0.1,
            time_constant,
            gram: [[0.0; N]; N],
            moment: [0.0; N],
            mean_square: [0.0; N],
            weight: 0.0,
            theta,
        }
    }

    /// The current parameters.
    pub(crate) fn parameters(&self) -> [f64; N] {
        self.theta
    }

    /// `θ·x`.
    pub(crate) fn predict(&self, x: &[f64; N]) -> f64 {
        self.theta.iter().zip(x).map(|(t, x)| t * x).sum()
    }

    /// Learns one observation `y ≈ θ·x` with weight `w` (0..=1), `dt` seconds after the
    /// previous one. Non-finite inputs, a negative weight or `dt` are ignored.
    pub(crate) fn update(&mut self, x: &[f64; N], y: f64, w: f64, dt: f64) {
        if !(y.is_finite() && w.is_finite() && w >= 0.0 && dt.is_finite() && dt >= 0.0)
            || x.iter().any(|v| !v.is_finite())
        {
            return;
        }
        let forget = if self.time_constant > 0.0 {
            (-dt / self.time_constant).exp()
        } else {
            0.0
        };
        for j in 0..N {
            self.moment[j] = forget * self.moment[j] + w * x[j] * y;
            for k in 0..N {
                self.gram[j][k] = forget * self.gram[j][k] + w * x[j] * x[k];
            }
        }
        // The excitation the prior is measured against forgets like the data, but counts
        // every frame, whatever its weight: a run of outliers does not weaken the prior.
        self.weight = forget * self.weight + 1.0;
        for (square, x) in self.mean_square.iter_mut().zip(x) {
            *square = forget * *square + x * x;
        }
        self.solve();
    }

    fn solve(&mut self) {
        let mut a = self.gram;
        let mut b = self.moment;
        for j in 0..N {
            let strength = self.prior_frames * self.mean_square[j] / self.weight.max(1e-12) + 1e-18;
            a[j][j] += strength;
            b[j] += strength * self.prior[j];
        }
        if let Some(theta) = solve(a, b) {
            self.theta = core::array::from_fn(|j| {
                if theta[j].is_finite() {
                    theta[j].clamp(self.lower[j], self.upper[j])
                } else {
                    self.prior[j]
                }
            });
        }
    }
}

/// Gaussian elimination with partial pivoting; `None` when singular.
fn solve<const N: usize>(mut a: [[f64; N]; N], mut b: [f64; N]) -> Option<[f64; N]> {
    for col in 0..N {
        let pivot = (col..N).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[pivot][col].abs() < 1e-300 {
            return None;
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        let pivot_row = a[col];
        for row in col + 1..N {
            let f = a[row][col] / pivot_row[col];
            for k in col..N {
                a[row][k] -= f * pivot_row[k];
            }
            b[row] -= f * b[col];
        }
    }
    let mut x = [0.0; N];
    for row in (0..N).rev() {
        let rest: f64 = (row + 1..N).map(|k| a[row][k] * x[k]).sum();
        x[row] = (b[row] - rest) / a[row][row];
    }
    Some(x)
}

/// Down-weights observations far from the prediction (Huber weights): within
/// [`HUBER_ERRORS`] typical errors an observation counts fully, beyond it in inverse
/// proportion to its error. The typical error follows about a second of observations,
/// each capped so that one stall does not open the gate for the next.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct RobustGate {
    typical: f32,
    floor: f32,
}

/// Observations within this many typical errors of the prediction count fully.
pub(crate) const HUBER_ERRORS: f32 = 3.0;

impl RobustGate {
    /// A gate whose typical error starts at `initial` and is never taken below `floor`
    /// (a source with no noise at all would otherwise call any change an outlier).
    pub(crate) fn new(initial: f32, floor: f32) -> Self {
        Self {
            typical: initial,
            floor,
        }
    }

    /// The typical error now (never below the floor).
    pub(crate) fn typical(&self) -> f32 {
        self.typical.max(self.floor)
    }

    /// The weight of an observation `error` away from the prediction (0..=1).
    pub(crate) fn weight(&self, error: f32) -> f32 {
        let bound = HUBER_ERRORS * self.typical.max(self.floor);
        let error = error.abs();
        if error <= bound || !error.is_finite() {
            if error.is_finite() { 1.0 } else { 0.0 }
        } else {
            bound / error
        }
    }

    /// Takes the error of an observation `dt` seconds after the previous one.
    pub(crate) fn observe(&mut self, error: f32, dt: f32) {
        if !(error.is_finite() && dt.is_finite() && dt > 0.0) {
            return;
        }
        let scale = self.typical.max(self.floor);
        let alpha = 1.0 - (-dt).exp();
        self.typical += alpha * (error.abs().min(4.0 * scale) - self.typical);
    }
}

/// How many deviations from the mean one observation of a [`LogSpread`] counts for at
/// most. At a still camera the tail goal's aim follows the spread: with a cap of 4, one
/// frame twice as long among frames that scatter by 15% opened the spread by a fifth and
/// cut the aim by a tenth at once, handing out anew (27% of a still camera's hand-outs
/// followed such an aim step, `docs/shimmer.md`). At 2.5 a normal scatter is still
/// learned within about 2% of its deviation (the quantile's calibration takes up the
/// rest), and a scatter that grows fourfold is followed within 18–23 frames (each frame
/// may widen it by 6–8% at 15–20 frames a second, against 17–21% with a cap of 4).
const SPREAD_CAP: f32 = 2.5;

/// How far measured times scatter around their predictions: an exponentially weighted
/// mean and standard deviation of `ln(measured / predicted)` over about
/// [`LogSpread::seconds`], so a change of the machine's noise is followed within about
/// that long. Each observation is capped at [`SPREAD_CAP`] deviations from the mean, so
/// that one stall does not open the spread for the frames after it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct LogSpread {
    mean: f32,
    variance: f32,
    seconds: f32,
    floor: f32,
}

impl LogSpread {
    /// A spread starting at `sigma` (a log deviation: 0.05 is about 5%), never taken below
    /// `floor`, following about `seconds` of observations.
    pub(crate) fn new(sigma: f32, floor: f32, seconds: f32) -> Self {
        Self {
            mean: 0.0,
            variance: sigma * sigma,
            seconds: seconds.max(1e-3),
            floor,
        }
    }

    /// The mean log ratio of measured to predicted (0: unbiased).
    #[cfg(test)]
    pub(crate) fn mean(&self) -> f32 {
        self.mean
    }

    /// The standard deviation of the log ratio (never below the floor).
    pub(crate) fn sigma(&self) -> f32 {
        self.variance.sqrt().max(self.floor)
    }

    /// The factor on a prediction that the measurement stays below with `z` standard
    /// deviations to spare: `exp(mean + z·σ)`.
    pub(crate) fn quantile_factor(&self, z: f32) -> f32 {
        (self.mean + z * self.sigma()).exp()
    }

    /// Takes a measurement and its prediction, `dt` seconds after the previous one.
    /// Non-finite or non-positive times are ignored.
    pub(crate) fn observe(&mut self, predicted: f32, measured: f32, dt: f32) {
        let positive = |t: f32| t.is_finite() && t > 0.0;
        if !(positive(predicted) && positive(measured) && positive(dt)) {
            return;
        }
        let sigma = self.sigma();
        let x = (measured / predicted).ln();
        let x = x.clamp(
            self.mean - SPREAD_CAP * sigma,
            self.mean + SPREAD_CAP * sigma,
        );
        let alpha = 1.0 - (-dt / self.seconds).exp();
        let d = x - self.mean;
        self.mean += alpha * d;
        self.variance = (1.0 - alpha) * (self.variance + alpha * d * d);
    }
}

/// How far a quantile of a [`LogSpread`] must be moved for the share of measurements
/// above it to be what was asked: adaptive conformal inference (Gibbs & Candès 2021).
/// Each measurement above the quantile raises a log offset by `gain × (1 − share)`, each
/// one below lowers it by `gain × share`, so the offset stops moving when the share above
/// is the one asked, whatever the shape of the scatter (over `n` measurements the share
/// above is the one asked within `2 × limit / (gain × n)`). A log-normal
/// scatter needs no offset; the frame times measured on these machines have longer tails
/// (regimes that switch every few seconds, hitches): a quantile far out, such as the
/// 99th percentile, then lies beyond where the spread alone puts it.
///
/// The offset and its steps are log factors, not numbers of deviations: a hitch sits many
/// quiet deviations out, and steps that grew and shrank with the spread would weigh the
/// frames of a quiet moment (when hitches pass the quantile) less than the others, and
/// miss the share. The spread follows a change of the noise within seconds; the
/// offset only corrects its shape, which changes slowly, so it moves by little per frame
/// (a fraction of a percent of the aim) and a still picture stays still.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct QuantileCalibration {
    share: f32,
    offset: f32,
}

/// How far one measurement moves a [`QuantileCalibration`]'s offset, as a log factor.
const CALIBRATION_GAIN: f32 = 0.01;

/// The most a [`QuantileCalibration`] moves its quantile either way, as a log factor
/// (×2).
const CALIBRATION_LIMIT: f32 = core::f32::consts::LN_2;

impl QuantileCalibration {
    /// A calibration of the quantile above which `share` of measurements lie (taken
    /// within `1e-4..=0.5`; 0.05 when not finite), starting at the spread's own.
    pub(crate) fn new(share: f32) -> Self {
        let share = if share.is_finite() {
            share.clamp(1e-4, 0.5)
        } else {
            0.05
        };
        Self { share, offset: 0.0 }
    }

    /// The share of measurements it calibrates for.
    pub(crate) fn share(&self) -> f32 {
        self.share
    }

    /// The learned offset, as a log factor (0: the spread's own quantile).
    pub(crate) fn offset(&self) -> f32 {
        self.offset
    }

    /// The factor on a prediction that the share of measurements exceeds.
    pub(crate) fn factor(&self, spread: &LogSpread) -> f32 {
        let z = crate::budget::deadline::upper_normal_quantile(self.share);
        spread.quantile_factor(z) * self.offset.exp()
    }

    /// Takes a measurement, its prediction, and the [`factor`](Self::factor) this
    /// quantile had when the prediction was made. Non-finite or non-positive values are
    /// ignored.
    pub(crate) fn observe(&mut self, factor: f32, predicted: f32, measured: f32) {
        let positive = |t: f32| t.is_finite() && t > 0.0;
        if !(positive(factor) && positive(predicted) && positive(measured)) {
            return;
        }
        let above = measured > predicted * factor;
        let step = if above { 1.0 - self.share } else { -self.share };
        self.offset =
            (self.offset + CALIBRATION_GAIN * step).clamp(-CALIBRATION_LIMIT, CALIBRATION_LIMIT);
    }
}

/// The largest state a [`CostFilter`] keeps: the speed and up to seven costs.
const MAX_STATE: usize = 8;

/// A cost learned online: `speed · θ·x`, with `θ` what each regressor costs and `speed`
/// how much faster or slower than that the machine runs now, estimated together by an
/// extended Kalman filter on `ln(measured) = ln(speed) + ln(θ·x) + noise`, each cost
/// kept as a log factor on its prior (`θⱼ = priorⱼ · e^vⱼ`).
///
/// Why a filter and not a regression plus a smoothed ratio: a frame off its prediction
/// may mean that the machine changed speed, or that one regressor's cost is wrong, and
/// only how the regressors vary tells the two apart. A fast ratio alone would explain
/// away every error before a regression could see which regressor caused it; a
/// regression alone would bend its costs at every change of speed. The filter keeps both
/// uncertainties and splits each error by them: at first the costs are as uncertain as
/// the calibration (a factor of about 3), and learn quickly from frames whose mix of
/// regressors varies; once they are known, a change that moves every frame alike goes to
/// the speed.
///
/// Both drift as random walks sized per elapsed second, not per frame, so that the
/// behaviour does not depend on the frame rate: with known costs the speed follows the
/// measured ratio with the time constant `speed_seconds` (as an exponential average
/// would), and a cost follows a lasting change of its own with `costs_seconds`. A
/// regressor that stays 0 keeps its cost (its prior, if it was never seen).
///
/// A frame whose error is beyond [`HUBER_ERRORS`] typical errors counts as if it were at
/// that bound, unless the frame before was beyond it on the same side: one hitch moves
/// little, a step in speed is followed from its second frame. Whatever a frame says, it
/// moves neither the speed nor any cost by more than [`MAX_STEP_FACTOR`], and the drift
/// counts at most [`MAX_DRIFT_SECONDS`] of the time since the previous frame: a frame
/// that came after a long stall is no more trusted than one that came on time.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct CostFilter<const N: usize> {
    prior: [f64; N],
    lower: [f64; N],
    upper: [f64; N],
    speed_seconds: f64,
    costs_seconds: f64,
    /// `ln(speed)`, then each cost's log factor on its prior.
    state: [f64; MAX_STATE],
    covariance: [[f64; MAX_STATE]; MAX_STATE],
    gate: RobustGate,
    /// The typical error of the parts measured on their own ([`learn_part`](Self::learn_part)),
    /// which weighs them: a part timed by a clock that scatters more than the whole, or
    /// that disagrees with it, moves the costs less.
    part_gate: RobustGate,
    /// The time between the last two frames learned, seconds (the parts' gate follows
    /// the frames).
    last_dt: f32,
    /// The previous frame's error was beyond the gate, on this side (−1, 0 or 1).
    last_outlier: i8,
}

/// The most one frame moves the speed or any one cost, as a factor either way.
pub(crate) const MAX_STEP_FACTOR: f64 = 1.5;

/// The most time between two frames that the random walks count, seconds.
pub(crate) const MAX_DRIFT_SECONDS: f32 = 1.0;

/// One spread of the calibration's uncertainty, as a log factor: about ×3 either way.
pub(crate) const PRIOR_SPREAD: f64 = 1.1;

/// One spread of a per-primitive cost's uncertainty, as a log factor, when the
/// calibration was measured on the renderer in use: about ×1.4 either way. What a family
/// costs beside the others is a property of the renderer; the machine's speed, which
/// moves them all alike, is learned apart. With the wide spread a few noisy frames of
/// varied mixes set the families' relative costs where the noise put them, and a still
/// scene, whose mix never changes, kept them there.
pub(crate) const MEASURED_PRIOR_SPREAD: f64 = 0.35;

/// The smallest prior a cost takes (a log factor needs a positive base).
const MIN_PRIOR: f64 = 1e-9;

impl<const N: usize> CostFilter<N> {
    /// A filter starting at `prior`, each cost kept within `lower..=upper` (clamped to
    /// positive values), the speed following the machine within `speed_seconds` and the
    /// costs within `costs_seconds`.
    pub(crate) fn new(
        prior: [f64; N],
        lower: [f64; N],
        upper: [f64; N],
        speed_seconds: f32,
        costs_seconds: f32,
    ) -> Self {
        assert!(
            N < MAX_STATE,
            "a cost filter keeps at most {} costs",
            MAX_STATE - 1
        );
        let prior = prior.map(|p| if p.is_finite() { p.max(MIN_PRIOR) } else { 1.0 });
        let mut covariance = [[0.0; MAX_STATE]; MAX_STATE];
        for (i, row) in covariance.iter_mut().enumerate().take(N + 1) {
            row[i] = PRIOR_SPREAD * PRIOR_SPREAD;
        }
        let mut state = [0.0; MAX_STATE];
        for j in 0..N {
            state[j + 1] = (prior[j].clamp(lower[j].max(MIN_PRIOR), upper[j]) / prior[j]).ln();
        }
        Self {
            prior,
            lower: lower.map(|l| l.max(MIN_PRIOR)),
            upper,
            speed_seconds: f64::from(speed_seconds).max(1e-3),
            costs_seconds: f64::from(costs_seconds).max(1e-3),
            state,
            covariance,
            gate: RobustGate::new(0.1, 0.02),
            part_gate: RobustGate::new(0.1, 0.02),
            last_dt: 0.0,
            last_outlier: 0,
        }
    }

    /// This filter with one spread of each cost's prior uncertainty (a log factor;
    /// [`PRIOR_SPREAD`] unless set): how far a few frames may move it before their mix
    /// has told the costs apart. Spreads that are not finite and positive are ignored.
    pub(crate) fn with_prior_spreads(mut self, spreads: [f64; N]) -> Self {
        for (j, spread) in spreads.into_iter().enumerate() {
            if spread.is_finite() && spread > 0.0 {
                self.covariance[j + 1][j + 1] = spread * spread;
            }
        }
        self
    }

    /// How much slower (above 1) the machine runs now than the costs say.
    pub(crate) fn speed(&self) -> f32 {
        self.state[0].exp() as f32
    }

    /// What each regressor costs (at speed 1).
    pub(crate) fn costs(&self) -> [f64; N] {
        core::array::from_fn(|j| self.prior[j] * self.state[j + 1].exp())
    }

    /// `θ·x`: the cost at speed 1.
    pub(crate) fn base(&self, x: &[f64; N]) -> f64 {
        self.costs().iter().zip(x).map(|(c, x)| c * x).sum()
    }

    /// The predicted time of `x`: `speed · θ·x`, seconds.
    pub(crate) fn predict(&self, x: &[f64; N]) -> f32 {
        (self.base(x) * self.state[0].exp()) as f32
    }

    /// Learns that `x` took `measured` seconds, `dt` seconds after the previous frame.
    /// Times that are not finite and positive, or a regressor that is not finite, are
    /// ignored.
    pub(crate) fn learn(&mut self, x: &[f64; N], measured: f32, dt: f32) {
        if !(usable(x, measured) && dt.is_finite() && dt > 0.0) {
            return;
        }
        let noise = self.noise();
        self.drift(f64::from(dt.min(MAX_DRIFT_SECONDS)), noise * noise);
        self.last_dt = dt;
        if let Some(error) = self.correct(x, measured, true) {
            self.gate.observe(error as f32, dt);
        }
    }

    /// Learns that a part of a frame already learned — the regressors `x` names, the
    /// others 0 — took `measured` seconds: a second measurement of the same frame (the
    /// forest pass's own GPU time, say, against the whole rendering), which tells the
    /// parts apart where the whole alone cannot (a fixed part and a per-primitive cost
    /// rise and fall together when the scene's mix hardly changes). Nothing drifts; the
    /// part is weighed by its own typical error, which follows how far parts have
    /// landed from their predictions (a clock that scatters, or one that times less than
    /// the part — a software rasteriser's timestamps — counts for little), and an error
    /// beyond [`HUBER_ERRORS`] of it always counts as at the bound. Ignored like
    /// [`learn`](Self::learn)'s bad input.
    pub(crate) fn learn_part(&mut self, x: &[f64; N], measured: f32) {
        if usable(x, measured)
            && let Some(error) = self.correct(x, measured, false)
        {
            self.part_gate.observe(error as f32, self.last_dt);
        }
    }

    /// The filter's measurement update for `x` taking `measured` seconds; returns the
    /// error it corrected (log of measured over predicted), if it could.
    fn correct(&mut self, x: &[f64; N], measured: f32, whole: bool) -> Option<f64> {
        let gate = if whole { self.gate } else { self.part_gate };
        let noise = noise_of(gate);
        let costs = self.costs();
        let base: f64 = costs.iter().zip(x).map(|(c, x)| c * x).sum();
        if base <= 0.0 {
            return None;
        }
        let n = N + 1;
        let error = f64::from(measured).ln() - self.state[0] - base.ln();
        // ∂ ln(prediction) / ∂ state: 1 for the speed, each regressor's share for its cost.
        let mut h = [0.0; MAX_STATE];
        h[0] = 1.0;
        for j in 0..N {
            h[j + 1] = costs[j] * x[j] / base;
        }
        let bound = f64::from(HUBER_ERRORS * gate.typical());
        let side = if error.abs() > bound {
            error.signum() as i8
        } else {
            0
        };
        let mut variance = noise * noise;
        if side != 0 && (!whole || side != self.last_outlier) {
            // An isolated outlier: as if it were at the bound.
            variance *= (error / bound).powi(2);
        }
        if whole {
            self.last_outlier = side;
        }
        // K = P h / (h' P h + r); x += K e; P -= K h' P.
        let mut ph = [0.0; MAX_STATE];
        for (i, v) in ph.iter_mut().enumerate().take(n) {
            *v = (0..n).map(|k| self.covariance[i][k] * h[k]).sum();
        }
        let innovation: f64 = (0..n).map(|i| h[i] * ph[i]).sum::<f64>() + variance;
        if !(innovation.is_finite() && innovation > 0.0) {
            return None;
        }
        // The whole step is shortened, not each part, so that its direction stays the
        // filter's.
        let largest = (0..n)
            .map(|i| (ph[i] / innovation * error).abs())
            .fold(0.0, f64::max);
        let shorten = (MAX_STEP_FACTOR.ln() / largest).min(1.0);
        for i in 0..n {
            let gain = ph[i] / innovation;
            self.state[i] += gain * error * shorten;
            for (p, ph) in self.covariance[i][..n].iter_mut().zip(&ph[..n]) {
                *p -= gain * ph;
            }
        }
        for i in 0..n {
            for k in 0..i {
                let mean = 0.5 * (self.covariance[i][k] + self.covariance[k][i]);
                self.covariance[i][k] = mean;
                self.covariance[k][i] = mean;
            }
            self.covariance[i][i] = self.covariance[i][i].max(1e-30);
        }
        let most = MAX_SPEED.ln();
        self.state[0] = self.state[0].clamp(-most, most);
        for j in 0..N {
            let v = self.state[j + 1];
            let lo = (self.lower[j] / self.prior[j]).ln();
            let hi = (self.upper[j] / self.prior[j]).ln();
            self.state[j + 1] = if v.is_finite() {
                v.clamp(lo, hi.max(lo))
            } else {
                0.0
            };
        }
        Some(error)
    }

    /// The measurement noise's standard deviation (of the log error) the typical error
    /// stands for.
    fn noise(&self) -> f64 {
        noise_of(self.gate)
    }

    /// The random walks over `dt` seconds, for measurements of variance `variance`.
    fn drift(&mut self, dt: f64, variance: f64) {
        // With its other parts known, a state whose walk is `r α² / (1 − α)` per frame
        // follows a lasting change with the gain `α` an exponential average with time
        // constant τ gives a frame `dt` long.
        let walk = |seconds: f64| {
            let alpha = (1.0 - (-dt / seconds).exp()).min(0.999);
            variance * alpha * alpha / (1.0 - alpha)
        };
        self.covariance[0][0] += walk(self.speed_seconds);
        let costs = walk(self.costs_seconds);
        for j in 1..=N {
            self.covariance[j][j] += costs;
        }
    }
}

/// The standard deviation (of the log error) of measurements whose typical error `gate`
/// follows: for normal errors the mean absolute one is σ·√(2/π).
fn noise_of(gate: RobustGate) -> f64 {
    f64::from(gate.typical()) * core::f64::consts::FRAC_PI_2.sqrt()
}

/// Whether a measurement `measured` of regressors `x` can be learned from: a finite,
/// positive time and finite regressors.
fn usable<const N: usize>(x: &[f64; N], measured: f32) -> bool {
    measured.is_finite() && measured > 0.0 && x.iter().all(|v| v.is_finite())
}

/// The most a [`CostFilter`]'s speed may differ from 1, as a ratio.
const MAX_SPEED: f64 = 1000.0;

#[cfg(test)]
mod tests {
    use super::*;

    fn bounds<const N: usize>() -> ([f64; N], [f64; N]) {
        ([0.0; N], [1e9; N])
    }

    #[test]
    fn the_regression_finds_two_costs_from_varied_frames() {
        let (lo, hi) = bounds::<2>();
        let mut r = PriorRegression::new([1.0, 1.0], lo, hi, 5.0);
        for i in 0..200 {
            let x = [1.0 + (i % 7) as f64, 3.0 - (i % 5) as f64 * 0.5];
            r.update(&x, 2.0 * x[0] + 0.5 * x[1], 1.0, 0.05);
        }
        let t = r.parameters();
        assert!(
            (t[0] - 2.0).abs() < 0.05 && (t[1] - 0.5).abs() < 0.05,
            "{t:?}"
        );
    }

    #[test]
    fn a_regressor_that_is_never_excited_keeps_its_prior() {
        let (lo, hi) = bounds::<3>();
        let mut r = PriorRegression::new([1.0, 2.0, 3.0], lo, hi, 5.0);
        for i in 0..300 {
            let x = [1.0, (i % 9) as f64, 0.0];
            r.update(&x, 0.5 + 4.0 * x[1], 1.0, 0.05);
        }
        let t = r.parameters();
        assert_eq!(t[2], 3.0);
        assert!(
            (t[0] - 0.5).abs() < 0.05 && (t[1] - 4.0).abs() < 0.05,
            "{t:?}"
        );
    }

    #[test]
    fn collinear_regressors_stay_finite_and_near_the_prior_split() {
        let (lo, hi) = bounds::<2>();
        let mut r = PriorRegression::new([1.0, 1.0], lo, hi, 5.0);
        for i in 0..300 {
            let s = 1.0 + (i % 4) as f64;
            r.update(&[s, s], 3.0 * s, 1.0, 0.05);
        }
        let t = r.parameters();
        assert!(t.iter().all(|v| v.is_finite()));
        // The sum is what the data say; the split is the prior's (equal).
        assert!((t[0] + t[1] - 3.0).abs() < 0.05, "{t:?}");
        assert!((t[0] - t[1]).abs() < 0.05, "{t:?}");
    }

    #[test]
    fn bad_inputs_are_ignored() {
        let (lo, hi) = bounds::<1>();
        let mut r = PriorRegression::new([1.0], lo, hi, 5.0);
        r.update(&[f64::NAN], 1.0, 1.0, 0.1);
        r.update(&[1.0], f64::INFINITY, 1.0, 0.1);
        r.update(&[1.0], 1.0, -1.0, 0.1);
        assert_eq!(r.parameters(), [1.0]);
    }

    fn filter() -> CostFilter<2> {
        CostFilter::new([0.01, 1.0], [0.0, 0.01], [1.0, 100.0], 0.25, 30.0)
    }

    #[test]
    fn the_filter_follows_a_step_in_speed_and_ignores_one_hitch() {
        let mut f = filter();
        let truth = |x: &[f64; 2]| (0.02 * x[0] + 1.5 * x[1]) as f32;
        let xs = [[1.0, 0.02], [1.0, 0.05], [1.0, 0.01]];
        for i in 0..600 {
            let x = xs[i % 3];
            f.learn(&x, truth(&x), 0.05);
        }
        let x = [1.0, 0.03];
        assert!(
            (f.predict(&x) / truth(&x) - 1.0).abs() < 0.01,
            "{:?}",
            f.costs()
        );
        let before = f.predict(&x);
        f.learn(&x, 10.0 * truth(&x), 0.05);
        assert!(
            (f.predict(&x) / before - 1.0).abs() < 0.02,
            "a hitch moved it"
        );
        let (speed, costs) = (f.speed(), f.costs());
        for _ in 0..20 {
            f.learn(&x, 1.4 * truth(&x), 0.05);
        }
        assert!((f.predict(&x) / (1.4 * truth(&x)) - 1.0).abs() < 0.03);
        // The step went to the speed, not to the costs.
        assert!(
            (f.speed() / speed - 1.4).abs() < 0.05,
            "{} → {}",
            speed,
            f.speed()
        );
        for (a, b) in costs.iter().zip(f.costs()) {
            assert!((b / a - 1.0).abs() < 0.03, "{costs:?} → {:?}", f.costs());
        }
    }

    /// A debugger or a blocking load: frames far off, one after the other, after a long
    /// wait each. However far off, no frame moves the speed or a cost by more than
    /// `MAX_STEP_FACTOR`.
    #[test]
    fn no_frame_moves_the_filter_by_more_than_its_bound() {
        let mut f = filter();
        let x = [1.0, 0.03];
        for _ in 0..200 {
            f.learn(&x, 0.05, 0.05);
        }
        for measured in [5.0, 50.0, 0.0005, 500.0] {
            for _ in 0..3 {
                let (speed, costs) = (f.speed(), f.costs());
                f.learn(&x, measured, 10.0);
                let moved = (f64::from(f.speed() / speed)).ln().abs();
                assert!(
                    moved <= MAX_STEP_FACTOR.ln() + 1e-6,
                    "speed ×{}",
                    moved.exp()
                );
                for (a, b) in costs.iter().zip(f.costs()) {
                    assert!(
                        (b / a).ln().abs() <= MAX_STEP_FACTOR.ln() + 1e-9,
                        "{a} → {b}"
                    );
                }
            }
        }
    }

    /// A scene whose mix never changes: the whole alone cannot say how much of it is
    /// fixed; the part measured on its own can.
    #[test]
    fn a_measured_part_tells_a_fixed_cost_from_a_per_primitive_one() {
        // Truth: 16 ms fixed, 30 ms of primitives. Prior: 40 ms fixed, 6 ms of primitives
        // (the same whole, so the whole has nothing to correct).
        let x = [1.0, 0.03];
        let prior = CostFilter::new([0.04, 0.2], [0.0, 0.01], [1.0, 100.0], 0.25, 30.0);
        let split = |f: &CostFilter<2>| {
            let c = f.costs();
            let speed = f64::from(f.speed());
            (c[0] * speed, c[1] * x[1] * speed)
        };
        let (mut whole_only, mut with_part) = (prior.clone(), prior);
        for i in 0..200 {
            // The machine's speed wanders by ±10%.
            let speed = 1.0 + 0.1 * ((i as f64) * 0.3).sin();
            let (fixed, primitives) = (0.016 * speed, 0.03 * speed);
            whole_only.learn(&x, (fixed + primitives) as f32, 0.05);
            with_part.learn(&x, (fixed + primitives) as f32, 0.05);
            with_part.learn_part(&[0.0, x[1]], primitives as f32);
        }
        let (fixed, primitives) = split(&with_part);
        assert!(
            (fixed / 0.016 - 1.0).abs() < 0.15 && (primitives / 0.03 - 1.0).abs() < 0.1,
            "with the part: fixed {fixed}, primitives {primitives}"
        );
        let (fixed, _) = split(&whole_only);
        assert!(
            fixed > 0.03,
            "the whole alone kept the prior's split: fixed {fixed}"
        );
        // Bad parts are ignored.
        let before = with_part.clone();
        with_part.learn_part(&[0.0, f64::NAN], 0.03);
        with_part.learn_part(&[0.0, x[1]], f32::NAN);
        with_part.learn_part(&[0.0, x[1]], -1.0);
        with_part.learn_part(&[0.0, 0.0], 0.03);
        assert_eq!(with_part, before);
    }

    /// A still scene on a software renderer (lavapipe): after a few frames of other mixes
    /// (the camera settling) the selection, and with it the mix, never changes; the whole
    /// frame scatters by 10% and the pass's own timestamps by 30%. Nothing but those few
    /// frames tells the families apart, so how far they move a family's cost is the
    /// prior's to say: a selection that later changes its mix (a still scene handing out
    /// anew) is priced by that cost. Returns, for `runs` seeds, the largest family's
    /// |log factor| off the truth after 10 s.
    fn still_scene_wander(spread: f64, runs: u64) -> Vec<f64> {
        let truth = [0.006, 1.0, 1.0, 1.0];
        let mix = [1.0, 0.0016, 0.0057, 0.0026];
        let whole = |x: &[f64; 4]| truth.iter().zip(x).map(|(c, x)| c * x).sum::<f64>();
        (1..=runs)
            .map(|seed| {
                let mut f = CostFilter::new(truth, [0.0; 4], [10.0; 4], 0.25, 30.0)
                    .with_prior_spreads([PRIOR_SPREAD, spread, spread, spread]);
                let mut normal = normals_from(seed);
                for i in 0..400 {
                    let x = if i < 10 {
                        [1.0, mix[1] * (1.0 + f64::from(i % 3)), mix[2], mix[3] * 0.5]
                    } else {
                        mix
                    };
                    let part = whole(&x) - truth[0] * x[0];
                    let mut noisy =
                        |sigma: f32, t: f64| (t * f64::from((sigma * normal()).exp())) as f32;
                    f.learn(&x, noisy(0.1, whole(&x)), 0.025);
                    f.learn_part(&[0.0, x[1], x[2], x[3]], noisy(0.3, part));
                }
                let costs = f.costs();
                costs[1..].iter().map(|c| c.ln().abs()).fold(0.0, f64::max)
            })
            .collect()
    }

    /// With a calibration measured on the renderer in use, the families' costs stay
    /// near it through a still scene: on lavapipe, with the spread of an unmeasured one,
    /// the triangles' cost went ×0.33 within a second and a still scene that then handed
    /// out anew drew 12 times as many triangles, priced at a third of what they cost.
    #[test]
    fn costs_the_mix_cannot_tell_apart_stay_near_a_measured_calibration() {
        let median = |mut v: Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let measured = median(still_scene_wander(MEASURED_PRIOR_SPREAD, 9));
        let unmeasured = median(still_scene_wander(PRIOR_SPREAD, 9));
        assert!(
            measured < 1.25_f64.ln() && measured < 0.6 * unmeasured,
            "median wander ×{:.2} with a measured calibration, ×{:.2} without",
            measured.exp(),
            unmeasured.exp()
        );
    }

    #[test]
    fn the_filter_learns_a_factor_of_three_within_two_seconds() {
        for truth in [3.0, 1.0 / 3.0] {
            let mut f = filter();
            let dt = 0.05;
            let mut i = 0;
            while f64::from(i) * dt < 2.0 {
                let x = [1.0, 0.02 + 0.01 * f64::from(i % 3)];
                f.learn(&x, (truth * (0.01 + x[1])) as f32, dt as f32);
                i += 1;
            }
            let x = [1.0, 0.03];
            let predicted = f.predict(&x);
            let measured = (truth * 0.04) as f32;
            assert!(
                (predicted / measured - 1.0).abs() < 0.05,
                "×{truth}: {predicted} vs {measured}"
            );
        }
    }

    #[test]
    fn the_filter_ignores_bad_inputs_and_keeps_an_unseen_cost() {
        let mut f = filter();
        f.learn(&[f64::NAN, 1.0], 0.1, 0.1);
        f.learn(&[1.0, 1.0], f32::NAN, 0.1);
        f.learn(&[1.0, 1.0], -1.0, 0.1);
        f.learn(&[1.0, 1.0], 0.1, 0.0);
        assert!((f.costs()[0] - 0.01).abs() < 1e-12 && (f.costs()[1] - 1.0).abs() < 1e-12);
        assert_eq!(f.speed(), 1.0);
        for _ in 0..200 {
            f.learn(&[1.0, 0.0], 0.03, 0.05);
        }
        assert!(
            (f.costs()[1] - 1.0).abs() < 1e-12,
            "a regressor that stays 0 keeps its prior"
        );
        assert!((f.predict(&[1.0, 0.0]) - 0.03).abs() < 0.001);
    }

    /// Uniform numbers in (0, 1) from a fixed seed (xorshift).
    fn uniforms(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed;
        move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        }
    }

    /// Standard normal numbers from a fixed seed.
    fn normals() -> impl FnMut() -> f32 {
        box_muller(uniforms(0x2545_F491_4F6C_DD1D))
    }

    /// Standard normal numbers from `seed` (spread over the bits first: xorshift starts
    /// slowly from a small one).
    fn normals_from(seed: u64) -> impl FnMut() -> f32 {
        box_muller(uniforms(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1))
    }

    /// Standard normal numbers from uniform ones (Box–Muller).
    fn box_muller(mut uniform: impl FnMut() -> f64) -> impl FnMut() -> f32 {
        move || {
            let (u, v) = (uniform(), uniform());
            ((-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()) as f32
        }
    }

    #[test]
    fn the_spread_follows_the_noise_up_and_down() {
        let mut normal = normals();
        let mut spread = LogSpread::new(0.05, 0.005, 1.0);
        let dt = 0.05;
        let mut run = |spread: &mut LogSpread, sigma: f32, frames: usize| {
            for _ in 0..frames {
                let measured = 0.030 * (sigma * normal()).exp();
                spread.observe(0.030, measured, dt);
            }
        };
        run(&mut spread, 0.10, 200);
        let noisy = spread.sigma();
        assert!((0.07..0.13).contains(&noisy), "σ 0.10 learned as {noisy}");
        // Quiet again: within three seconds the spread has followed most of the way.
        run(&mut spread, 0.02, 60);
        let quiet = spread.sigma();
        assert!(quiet < 0.04, "σ 0.02 after 3 s still {quiet}");
        assert!(spread.mean().abs() < 0.03);
        // One stall barely opens it.
        spread.observe(0.030, 3.0, dt);
        assert!(
            spread.sigma() < 2.0 * quiet,
            "{} after a stall",
            spread.sigma()
        );
        // Nonsense is ignored.
        let before = spread;
        spread.observe(f32::NAN, 0.03, dt);
        spread.observe(0.03, 0.0, dt);
        spread.observe(0.03, 0.03, f32::INFINITY);
        assert_eq!(spread, before);
    }

    /// A still camera's noisy frames (15% scatter), then one frame twice as long as
    /// predicted: the spread opens by less than a tenth, so the tail goal's aim does not
    /// step down for one frame (with the cap at four deviations it opened by a fifth).
    #[test]
    fn one_long_frame_barely_opens_a_noisy_spread() {
        let mut normal = normals();
        let mut spread = LogSpread::new(0.15, 0.005, crate::cost::model::FRAME_SPREAD_SECONDS);
        let dt = 0.05;
        for _ in 0..400 {
            spread.observe(0.030, 0.030 * (0.15 * normal()).exp(), dt);
        }
        let before = spread.sigma();
        assert!((0.12..0.18).contains(&before), "σ 0.15 learned as {before}");
        spread.observe(0.030, 0.060, dt);
        let after = spread.sigma();
        assert!(
            after < 1.1 * before,
            "one frame twice as long opened the spread {before} → {after}"
        );
    }

    /// Frame times with a long tail (3% noise, and one frame in 25 a hitch of an
    /// exponentially distributed 25% on average): the spread alone puts its 99th
    /// percentile where several times 1% of frames exceed it; calibrated, about 1% do; and
    /// the 95th stays where it was right.
    #[test]
    fn a_calibrated_quantile_is_exceeded_by_its_share_whatever_the_tail() {
        let mut normal = normals();
        let mut uniform = uniforms(0x9E37_79B9_7F4A_7C15);
        let dt = 0.05;
        for share in [0.01, 0.05] {
            let mut spread = LogSpread::new(0.05, 0.005, 2.0);
            let mut calibration = QuantileCalibration::new(share);
            let (mut above_spread, mut above_calibrated, mut counted) = (0, 0, 0);
            for frame in 0..40_000 {
                let hitch = if uniform() < 0.04 {
                    -0.25 * (1.0 - uniform()).ln()
                } else {
                    0.0
                };
                let measured = 0.030 * (0.03 * normal() + hitch as f32).exp();
                if frame >= 2_000 {
                    counted += 1;
                    let z = crate::budget::deadline::upper_normal_quantile(share);
                    above_spread += usize::from(measured > 0.030 * spread.quantile_factor(z));
                    above_calibrated += usize::from(measured > 0.030 * calibration.factor(&spread));
                }
                calibration.observe(calibration.factor(&spread), 0.030, measured);
                spread.observe(0.030, measured, dt);
            }
            let (plain, calibrated) = (
                above_spread as f32 / counted as f32,
                above_calibrated as f32 / counted as f32,
            );
            eprintln!(
                "share {share}: {:.2}% above the spread's quantile, {:.2}% above the calibrated one",
                plain * 100.0,
                calibrated * 100.0
            );
            assert!(
                (calibrated - share).abs() <= 0.1 * share + 0.001,
                "share {share}: {:.2}% above the calibrated quantile",
                calibrated * 100.0
            );
            if share < 0.02 {
                assert!(plain > 2.0 * share, "the tail is not long enough to test");
            }
        }
        // Nonsense is ignored.
        let mut calibration = QuantileCalibration::new(0.05);
        let before = calibration;
        calibration.observe(1.1, f32::NAN, 0.03);
        calibration.observe(1.1, 0.03, -1.0);
        calibration.observe(f32::INFINITY, 0.03, 0.03);
        assert_eq!(calibration, before);
        assert_eq!(QuantileCalibration::new(f32::NAN).share(), 0.05);
    }
}
