//! The Runge–Kutta methods nudyn integrates with: Butcher tableaus and, for
//! the adaptive pairs, their error estimators and step-size controllers.
//! Coefficients are the published ones (Hairer, Nørsett & Wanner, Solving
//! Ordinary Differential Equations I, 2nd ed., §II.5 and §II.10; Bogacki &
//! Shampine, Appl. Math. Lett. 2, 1989; Tsitouras, Comput. Math. Appl. 62,
//! 2011), checked against the order conditions in the tests below.

/// How a method estimates the local error of a step from its stages.
#[derive(Clone, Copy, Debug)]
pub enum ErrorEstimate {
    /// Fixed step: no estimate.
    None,
    /// One embedded formula: the error is h·Σ eᵢkᵢ with these weights eᵢ.
    Embedded(&'static [f64]),
    /// DOP853's pair of estimators, of orders 5 and 3, combined as
    /// |e₅|² / √(n(|e₅|² + 0.01|e₃|²)) so that the estimate is of order 8
    /// yet does not vanish by accident where e₅ does.
    Dop853 {
        /// Weights of the 5th-order estimator.
        fifth: &'static [f64],
        /// Weights of the 3rd-order estimator.
        third: &'static [f64],
    },
}

/// A method's order and the constants of its step-size controller.
#[derive(Clone, Copy, Debug)]
pub struct StepControl {
    /// Order of the solution.
    pub order: u32,
    /// The error estimate, as it is held (`error_per`), scales as
    /// h^(1/exponent): the controller takes the new step as
    /// h·(1/err)^exponent.
    pub controller_exponent: f64,
    /// Bounds on the factor by which one step may shrink or grow the next.
    pub factor_bounds: (f64, f64),
    /// What each step's error estimate is held to.
    pub error_per: ErrorPer,
    /// The tolerance below which the part of the estimate that adds up is
    /// discounted for the gap between the estimate's order and the
    /// solution's (adaptive.rs, `order_gap_discount`); `None` holds it to
    /// the tolerance as asked.
    pub order_gap_anchor: Option<f64>,
}

/// What each step's error estimate is held to (adaptive.rs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ErrorPer {
    /// tol·h/(1 s): the error per unit step, so that a second's errors sum
    /// to about tol.
    UnitStep,
    /// tol·share, whatever the step, as stiff solvers hold it.
    Step {
        /// The share of the tolerance one step may take.
        share: f64,
    },
}

/// A Butcher tableau of an explicit Runge–Kutta method, with its error
/// estimator and step-size controller constants.
#[derive(Clone, Copy, Debug)]
pub struct Tableau {
    /// Strictly lower-triangular stage coefficients, row i has i entries.
    pub a: &'static [&'static [f64]],
    /// Weights.
    pub b: &'static [f64],
    /// Nodes.
    pub c: &'static [f64],
    /// Local error estimator.
    pub error: ErrorEstimate,
    /// Order and step-size controller.
    pub control: StepControl,
    /// Whether the last stage is evaluated at the step's result ("first same
    /// as last"), so that it is the next step's first stage.
    pub first_same_as_last: bool,
    /// Its continuous extension, if it has one: the solution anywhere within
    /// a step, from the step's stages.
    pub dense: Option<&'static DenseOutput>,
}

/// A continuous extension ("dense output") of an explicit method: the
/// solution at a share s ∈ [0, 1] of a step of size h from y₀ is
/// y(s) = y₀ + h·Σᵢ Bᵢ(s)kᵢ over the method's stages and the extra ones
/// below. Every one here is the cubic Hermite interpolant of the step's
/// two ends (y₀, its rate k₁, y₁ and the rate f(y₁) there) plus
/// corrections that vanish with their slopes at both ends, written in
/// Hairer's nested form
///     Bᵢ(s) = s(W₁ᵢ + (1−s)(W₂ᵢ + s(W₃ᵢ + (1−s)(W₄ᵢ + s(…))))),
/// with W₁ = b, W₂ = e₁ − b, W₃ = 2b − e₁ − e_end (the Hermite part) and
/// W₄, … the corrections.
#[derive(Clone, Copy, Debug)]
pub struct DenseOutput {
    /// The order of y(s) for every s.
    pub order: u32,
    /// Stages evaluated after the step, only where it is interpolated:
    /// their node and their row of a over every stage before them.
    pub extra: &'static [(f64, &'static [f64])],
    /// The stage evaluated at the step's result y₁ (f(y₁)).
    pub end_stage: usize,
    /// The rows W₄, … over the stages (entries beyond a row's length are 0).
    pub corrections: &'static [&'static [f64]],
}

/// The most rows of any dense output's nested form (DOP853's).
pub const DENSE_ROWS: usize = 7;

impl DenseOutput {
    /// The number of rows of its nested form.
    pub fn rows(&self) -> usize {
        3 + self.corrections.len()
    }

    /// Wⱼᵢ: row `row` (from 0) of the nested form at stage `stage`, for
    /// a method with weights `b`.
    pub fn weight(&self, b: &[f64], row: usize, stage: usize) -> f64 {
        let b = b.get(stage).copied().unwrap_or(0.0);
        let first = if stage == 0 { 1.0 } else { 0.0 };
        let end = if stage == self.end_stage { 1.0 } else { 0.0 };
        match row {
            0 => b,
            1 => first - b,
            2 => 2.0 * b - first - end,
            _ => self.corrections[row - 3].get(stage).copied().unwrap_or(0.0),
        }
    }
}

/// The nested form's value at s from its rows' values (`row(j)`, j from
/// 0 to `rows` − 1): s(r₀ + (1−s)(r₁ + s(r₂ + …))).
pub fn nested(s: f64, rows: usize, row: impl Fn(usize) -> f64) -> f64 {
    (0..rows).rev().fold(0.0, |inner, j| (row(j) + inner) * if j % 2 == 0 { s } else { 1.0 - s })
}

/// The nested form's derivative in s at s, from its rows' values as in [`nested`].
pub fn nested_slope(s: f64, rows: usize, row: impl Fn(usize) -> f64) -> f64 {
    let (mut value, mut slope) = (0.0, 0.0);
    for j in (0..rows).rev() {
        let (factor, factor_slope) = if j % 2 == 0 { (s, 1.0) } else { (1.0 - s, -1.0) };
        let inner = row(j) + value;
        slope = slope * factor + inner * factor_slope;
        value = inner * factor;
    }
    slope
}

/// The classical 4th-order Runge–Kutta method.
pub const RK4: Tableau = Tableau {
    a: &[&[], &[0.5], &[0.0, 0.5], &[0.0, 0.0, 1.0]],
    b: &[1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0],
    c: &[0.0, 0.5, 0.5, 1.0],
    error: ErrorEstimate::None,
    control: StepControl {
        order: 4,
        controller_exponent: 0.0,
        factor_bounds: (1.0, 1.0),
        error_per: ErrorPer::UnitStep,
        order_gap_anchor: None,
    },
    first_same_as_last: false,
    dense: None,
};

/// Dormand–Prince 5(4): 7 stages, first same as last, so 6 evaluations per step.
pub const DOPRI5: Tableau = Tableau {
    a: &[
        &[],
        &[1.0 / 5.0],
        &[3.0 / 40.0, 9.0 / 40.0],
        &[44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0],
        &[19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0],
        &[9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0],
        &[35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0],
    ],
    b: &[35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0, 0.0],
    c: &[0.0, 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0, 1.0],
    // b − b̂, with b̂ the 4th-order weights.
    error: ErrorEstimate::Embedded(&[
        71.0 / 57600.0,
        0.0,
        -71.0 / 16695.0,
        71.0 / 1920.0,
        -17253.0 / 339200.0,
        22.0 / 525.0,
        -1.0 / 40.0,
    ]),
    control: StepControl {
        order: 5,
        controller_exponent: 1.0 / 4.0,
        factor_bounds: (0.2, 10.0),
        error_per: ErrorPer::UnitStep,
        order_gap_anchor: Some(FIFTH_ORDER_GAP_ANCHOR),
    },
    first_same_as_last: true,
    dense: Some(&DenseOutput {
        order: 4,
        extra: &[],
        end_stage: 6,
        // Shampine's (Math. Comp. 46, 1986), as Hairer's DOPRI5 gives it.
        corrections: &[&[
            -12715105075.0 / 11282082432.0,
            0.0,
            87487479700.0 / 32700410799.0,
            -10690763975.0 / 1880347072.0,
            701980252875.0 / 199316789632.0,
            -1453857185.0 / 822651844.0,
            69997945.0 / 29380423.0,
        ]],
    }),
};

/// Bogacki–Shampine 3(2): 4 stages, first same as last, so 3 evaluations
/// per step, the cheapest step of the pairs: for slow motion or loose
/// tolerances, where a step per communication step already meets the
/// tolerance.
pub const BS3: Tableau = Tableau {
    a: &[&[], &[0.5], &[0.0, 0.75], &[2.0 / 9.0, 1.0 / 3.0, 4.0 / 9.0]],
    b: &[2.0 / 9.0, 1.0 / 3.0, 4.0 / 9.0, 0.0],
    c: &[0.0, 0.5, 0.75, 1.0],
    // b − b̂, with b̂ = (7/24, 1/4, 1/3, 1/8) the 2nd-order weights.
    error: ErrorEstimate::Embedded(&[-5.0 / 72.0, 1.0 / 12.0, 1.0 / 9.0, -1.0 / 8.0]),
    // The estimate is of order 2: its local error O(h³), per unit step O(h²).
    control: StepControl {
        order: 3,
        controller_exponent: 1.0 / 2.0,
        factor_bounds: (0.2, 10.0),
        error_per: ErrorPer::UnitStep,
        // (q = 3, p̂ = 2) The 1 s fixtures delivered 0.04–0.3 of the
        // tolerance at 1e-4 and their tenth at 1e-6, the 10 s random trees
        // (tests/all/adaptive_integration.rs) 7–26 at 1e-4: anchored there,
        // tree 4 kept 25–28 from 1e-5 on, anchored at 1e-5 the welded strap
        // lay on the band's lower end (0.019–0.022) from 1e-5 on; at 3e-5,
        // 0.024–0.58 on the fixtures and 4.9–16 on the trees.
        order_gap_anchor: Some(3e-5),
    },
    first_same_as_last: true,
    // The cubic Hermite interpolant of the step's ends, of the method's own order.
    dense: Some(&DenseOutput { order: 3, extra: &[], end_stage: 3, corrections: &[] }),
};

// Tsitouras 5(4)'s coefficients, with the digits of his Table 1 (the first
// column from the row sums, as he gives it).
#[allow(clippy::excessive_precision)]
mod tsit5 {
    pub const C: [f64; 7] = [0.0, 0.161, 0.327, 0.9, 0.9800255409045097, 1.0, 1.0];
    pub const B: [f64; 7] =
        [0.09646076681806523, 0.01, 0.4798896504144996, 1.379008574103742, -3.290069515436081, 2.324710524099774, 0.0];
    pub const A: [&[f64]; 7] = [
        &[],
        &[0.161],
        &[-0.008480655492356989, 0.335480655492357],
        &[2.897153057105493, -6.359448489975075, 4.362295432869581],
        &[5.325864828439257, -11.74888356406283, 7.495539342889836, -0.09249506636175525],
        &[5.86145544294642, -12.92096931784711, 8.159367898576159, -0.071584973281401, -0.02826905039406838],
        &B_STAGES,
    ];
    const B_STAGES: [f64; 6] = [B[0], B[1], B[2], B[3], B[4], B[5]];
    /// b − b̂, with b̂ the 4th-order weights.
    pub const ERROR: [f64; 7] = [
        0.001780011052226,
        0.000816434459657,
        -0.007880878010262,
        0.144711007173263,
        -0.582357165452555,
        0.458082105929187,
        -1.0 / 66.0,
    ];
    /// The s⁴ coefficients of his interpolant's weights bᵢ(s) (a quartic in s
    /// through the step's ends with their slopes, so the cubic Hermite
    /// interpolant plus s²(1−s)² times these).
    pub const DENSE: [f64; 7] = [
        -1.0530884977290216,
        0.1017,
        2.490627285651253,
        -16.548102889244902,
        47.37952196281928,
        -34.87065786149661,
        2.5,
    ];
}

/// Tsitouras 5(4): 7 stages, first same as last, so 6 evaluations per step
/// as DOPRI5, with coefficients chosen for a smaller error of the 5th-order
/// solution instead of the simplifying assumptions DOPRI5 satisfies.
pub const TSIT5: Tableau = Tableau {
    a: &tsit5::A,
    b: &tsit5::B,
    c: &tsit5::C,
    error: ErrorEstimate::Embedded(&tsit5::ERROR),
    control: StepControl {
        order: 5,
        controller_exponent: 1.0 / 4.0,
        factor_bounds: (0.2, 10.0),
        error_per: ErrorPer::UnitStep,
        order_gap_anchor: Some(FIFTH_ORDER_GAP_ANCHOR),
    },
    first_same_as_last: true,
    dense: Some(&DenseOutput { order: 4, extra: &[], end_stage: 6, corrections: &[&tsit5::DENSE] }),
};

// DOP853's coefficients, with the digits Hairer publishes.
#[allow(clippy::excessive_precision)]
mod dop853 {
    pub const C: [f64; 12] = [
        0.0,
        0.526001519587677318785587544488e-01,
        0.789002279381515978178381316732e-01,
        0.118350341907227396726757197510e+00,
        0.281649658092772603273242802490e+00,
        1.0 / 3.0,
        0.25,
        4.0 / 13.0,
        127.0 / 195.0,
        0.6,
        6.0 / 7.0,
        1.0,
    ];
    pub const B: [f64; 12] = [
        5.42937341165687622380535766363e-2,
        0.0,
        0.0,
        0.0,
        0.0,
        4.45031289275240888144113950566e0,
        1.89151789931450038304281599044e0,
        -5.8012039600105847814672114227e0,
        3.1116436695781989440891606237e-1,
        -1.52160949662516078556178806805e-1,
        2.01365400804030348374776537501e-1,
        4.47106157277725905176885569043e-2,
    ];
    /// The weights b̂ of the 3rd-order solution, on stages 1, 9 and 12.
    const BHH: [f64; 3] =
        [0.244094488188976377952755905512, 0.733846688281611857341361741547, 0.220588235294117647058823529412e-01];
    pub const THIRD: [f64; 12] =
        [B[0] - BHH[0], 0.0, 0.0, 0.0, 0.0, B[5], B[6], B[7], B[8] - BHH[1], B[9], B[10], B[11] - BHH[2]];
    pub const FIFTH: [f64; 12] = [
        0.1312004499419488073250102996e-01,
        0.0,
        0.0,
        0.0,
        0.0,
        -0.1225156446376204440720569753e+01,
        -0.4957589496572501915214079952e+00,
        0.1664377182454986536961530415e+01,
        -0.3503288487499736816886487290e+00,
        0.3341791187130174790297318841e+00,
        0.8192320648511571246570742613e-01,
        -0.2235530786388629525884427845e-01,
    ];
    pub const A: [&[f64]; 12] = [
        &[],
        &[5.26001519587677318785587544488e-2],
        &[1.97250569845378994544595329183e-2, 5.91751709536136983633785987549e-2],
        &[2.95875854768068491816892993775e-2, 0.0, 8.87627564304205475450678981324e-2],
        &[
            2.41365134159266685502369798665e-1,
            0.0,
            -8.84549479328286085344864962717e-1,
            9.24834003261792003115737966543e-1,
        ],
        &[
            3.7037037037037037037037037037e-2,
            0.0,
            0.0,
            1.70828608729473871279604482173e-1,
            1.25467687566822425016691814123e-1,
        ],
        &[
            3.7109375e-2,
            0.0,
            0.0,
            1.70252211019544039314978060272e-1,
            6.02165389804559606850219397283e-2,
            -1.7578125e-2,
        ],
        &[
            3.70920001185047927108779319836e-2,
            0.0,
            0.0,
            1.70383925712239993810214054705e-1,
            1.07262030446373284651809199168e-1,
            -1.53194377486244017527936158236e-2,
            8.27378916381402288758473766002e-3,
        ],
        &[
            6.24110958716075717114429577812e-1,
            0.0,
            0.0,
            -3.36089262944694129406857109825e0,
            -8.68219346841726006818189891453e-1,
            2.75920996994467083049415600797e1,
            2.01540675504778934086186788979e1,
            -4.34898841810699588477366255144e1,
        ],
        &[
            4.77662536438264365890433908527e-1,
            0.0,
            0.0,
            -2.48811461997166764192642586468e0,
            -5.90290826836842996371446475743e-1,
            2.12300514481811942347288949897e1,
            1.52792336328824235832596922938e1,
            -3.32882109689848629194453265587e1,
            -2.03312017085086261358222928593e-2,
        ],
        &[
            -9.3714243008598732571704021658e-1,
            0.0,
            0.0,
            5.18637242884406370830023853209e0,
            1.09143734899672957818500254654e0,
            -8.14978701074692612513997267357e0,
            -1.85200656599969598641566180701e1,
            2.27394870993505042818970056734e1,
            2.49360555267965238987089396762e0,
            -3.0467644718982195003823669022e0,
        ],
        &[
            2.27331014751653820792359768449e0,
            0.0,
            0.0,
            -1.05344954667372501984066689879e1,
            -2.00087205822486249909675718444e0,
            -1.79589318631187989172765950534e1,
            2.79488845294199600508499808837e1,
            -2.85899827713502369474065508674e0,
            -8.87285693353062954433549289258e0,
            1.23605671757943030647266201528e1,
            6.43392746015763530355970484046e-1,
        ],
    ];

    /// The stages of the dense output, after the step: f(y₁) (stage 13,
    /// whose argument is y₁), then three more (Hairer's DOP853, c₁₄…c₁₆).
    pub const EXTRA: [(f64, &[f64]); 4] = [
        (1.0, &B),
        (
            0.1,
            &[
                5.61675022830479523392909219681e-2,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                2.53500210216624811088794765333e-1,
                -2.46239037470802489917441475441e-1,
                -1.24191423263816360469010140626e-1,
                1.5329179827876569731206322685e-1,
                8.20105229563468988491666602057e-3,
                7.56789766054569976138603589584e-3,
                -8.298e-3,
            ],
        ),
        (
            0.2,
            &[
                3.18346481635021405060768473261e-2,
                0.0,
                0.0,
                0.0,
                0.0,
                2.83009096723667755288322961402e-2,
                5.35419883074385676223797384372e-2,
                -5.49237485713909884646569340306e-2,
                0.0,
                0.0,
                -1.08347328697249322858509316994e-4,
                3.82571090835658412954920192323e-4,
                -3.40465008687404560802977114492e-4,
                1.41312443674632500278074618366e-1,
            ],
        ),
        (
            7.0 / 9.0,
            &[
                -4.28896301583791923408573538692e-1,
                0.0,
                0.0,
                0.0,
                0.0,
                -4.69762141536116384314449447206e0,
                7.68342119606259904184240953878e0,
                4.06898981839711007970213554331e0,
                3.56727187455281109270669543021e-1,
                0.0,
                0.0,
                0.0,
                -1.39902416515901462129418009734e-3,
                2.9475147891527723389556272149e0,
                -9.15095847217987001081870187138e0,
            ],
        ),
    ];

    /// The rows W₄ … W₇ of the dense output's nested form over the 16 stages.
    pub const DENSE: [&[f64]; 4] = [
        &[
            -0.84289382761090128651353491142e+01,
            0.0,
            0.0,
            0.0,
            0.0,
            0.56671495351937776962531783590e+00,
            -0.30689499459498916912797304727e+01,
            0.23846676565120698287728149680e+01,
            0.21170345824450282767155149946e+01,
            -0.87139158377797299206789907490e+00,
            0.22404374302607882758541771650e+01,
            0.63157877876946881815570249290e+00,
            -0.88990336451333310820698117400e-01,
            0.18148505520854727256656404962e+02,
            -0.91946323924783554000451984436e+01,
            -0.44360363875948939664310572000e+01,
        ],
        &[
            0.10427508642579134603413151009e+02,
            0.0,
            0.0,
            0.0,
            0.0,
            0.24228349177525818288430175319e+03,
            0.16520045171727028198505394887e+03,
            -0.37454675472269020279518312152e+03,
            -0.22113666853125306036270938578e+02,
            0.77334326684722638389603898808e+01,
            -0.30674084731089398182061213626e+02,
            -0.93321305264302278729567221706e+01,
            0.15697238121770843886131091075e+02,
            -0.31139403219565177677282850411e+02,
            -0.93529243588444783865713862664e+01,
            0.35816841486394083752465898540e+02,
        ],
        &[
            0.19985053242002433820987653617e+02,
            0.0,
            0.0,
            0.0,
            0.0,
            -0.38703730874935176555105901742e+03,
            -0.18917813819516756882830838328e+03,
            0.52780815920542364900561016686e+03,
            -0.11573902539959630126141871134e+02,
            0.68812326946963000169666922661e+01,
            -0.10006050966910838403183860980e+01,
            0.77771377980534432092869265740e+00,
            -0.27782057523535084065932004339e+01,
            -0.60196695231264120758267380846e+02,
            0.84320405506677161018159903784e+02,
            0.11992291136182789328035130030e+02,
        ],
        &[
            -0.25693933462703749003312586129e+02,
            0.0,
            0.0,
            0.0,
            0.0,
            -0.15418974869023643374053993627e+03,
            -0.23152937917604549567536039109e+03,
            0.35763911791061412378285349910e+03,
            0.93405324183624310003907691704e+02,
            -0.37458323136451633156875139351e+02,
            0.10409964950896230045147246184e+03,
            0.29840293426660503123344363579e+02,
            -0.43533456590011143754432175058e+02,
            0.96324553959188282948394950600e+02,
            -0.39177261675615439165231486172e+02,
            -0.14972683625798562581422125276e+03,
        ],
    ];
}

/// Dormand–Prince 8(5,3) (Hairer's DOP853): 12 stages, 8th order.
pub const DOP853: Tableau = Tableau {
    a: &dop853::A,
    b: &dop853::B,
    c: &dop853::C,
    error: ErrorEstimate::Dop853 { fifth: &dop853::FIFTH, third: &dop853::THIRD },
    control: StepControl {
        order: 8,
        controller_exponent: 1.0 / 7.0,
        factor_bounds: (1.0 / 3.0, 6.0),
        error_per: ErrorPer::UnitStep,
        // Its combined estimate scales nearly as the 8th-order solution's
        // error: the errors showed no trend with the tolerance from 1e-4 to
        // 1e-10 on 15 vehicles, and the power 1/8 its controller implies
        // moved them both ways (fixed_rig at 1e-8 0.0125 → 0.24 of the
        // tolerance, the limited arm at 1e-6 1.9 → 0.0034).
        order_gap_anchor: None,
    },
    first_same_as_last: false,
    // Of order 7, with three more evaluations (and f(y₁), the next step's first stage).
    dense: Some(&DenseOutput { order: 7, extra: &dop853::EXTRA, end_stage: 12, corrections: &dop853::DENSE }),
};

/// A Rosenbrock–W method as published (Hairer & Wanner, Solving Ordinary
/// Differential Equations II, §IV.7):
///     (I − hγW) kᵢ = h f(tₙ + αᵢh, yₙ + Σⱼ αᵢⱼkⱼ) + hW Σⱼ γᵢⱼkⱼ,
///     yₙ₊₁ = yₙ + Σ bᵢkᵢ, error estimate Σ (bᵢ − b̂ᵢ)kᵢ,
/// with αᵢ = Σⱼ αᵢⱼ. A W-method keeps its order whatever the matrix W
/// (the Jacobian ∂f/∂y only makes it stable on stiff modes), so W may be
/// an approximate Jacobian kept over several steps, and the time
/// derivative ∂f/∂t that a Rosenbrock method needs is left out.
#[derive(Clone, Copy, Debug)]
pub struct Rosenbrock {
    /// The diagonal γ.
    pub gamma: f64,
    /// Strictly lower-triangular αᵢⱼ, row i has i entries.
    pub alpha: &'static [&'static [f64]],
    /// Strictly lower-triangular γᵢⱼ, row i has i entries.
    pub gamma_below: &'static [&'static [f64]],
    /// Solution weights.
    pub b: &'static [f64],
    /// Weights of the embedded solution.
    pub b_hat: &'static [f64],
    /// Weights of a quadrature of the power over the step, on the stages'
    /// points.
    pub power_weights: &'static [f64],
    /// Order and step-size controller.
    pub control: StepControl,
}

/// The most stages of a Rosenbrock method.
pub const ROSENBROCK_STAGES: usize = 4;

/// A Rosenbrock method's coefficients in the form that needs no product
/// with W (Hairer & Wanner II, §IV.7, (7.25)): with Γ = (γᵢⱼ) including
/// the diagonal and uᵢ = Σⱼ γᵢⱼkⱼ,
///     (I/(hγ) − W) uᵢ = f(tₙ + αᵢh, yₙ + Σⱼ aᵢⱼuⱼ) + Σⱼ (cᵢⱼ/h)uⱼ,
///     yₙ₊₁ = yₙ + Σ mᵢuᵢ, error estimate Σ eᵢuᵢ,
/// where (aᵢⱼ) = (αᵢⱼ)Γ⁻¹, (cᵢⱼ) = diag(1/γ) − Γ⁻¹, m = bᵀΓ⁻¹ and
/// e = (b − b̂)ᵀΓ⁻¹.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RosenbrockStages {
    /// Number of stages.
    pub stages: usize,
    /// The diagonal γ.
    pub gamma: f64,
    /// The stage arguments' weights aᵢⱼ (strictly lower).
    pub a: [[f64; ROSENBROCK_STAGES]; ROSENBROCK_STAGES],
    /// The right-hand sides' weights cᵢⱼ (strictly lower).
    pub c: [[f64; ROSENBROCK_STAGES]; ROSENBROCK_STAGES],
    /// Time nodes αᵢ.
    pub nodes: [f64; ROSENBROCK_STAGES],
    /// Solution weights mᵢ.
    pub m: [f64; ROSENBROCK_STAGES],
    /// Error estimate weights eᵢ.
    pub e: [f64; ROSENBROCK_STAGES],
}

impl Rosenbrock {
    /// Its coefficients in the form of [`RosenbrockStages`].
    // Triangular matrix products read as the formulas do with indices.
    #[allow(clippy::needless_range_loop)]
    pub fn stages(&self) -> RosenbrockStages {
        let n = self.b.len();
        assert!(n <= ROSENBROCK_STAGES, "at most {ROSENBROCK_STAGES} stages");
        // Γ⁻¹ by forward substitution, column by column (Γ is lower triangular).
        let gamma = |i: usize, j: usize| if i == j { self.gamma } else { self.gamma_below[i][j] };
        let mut inverse = [[0.0; ROSENBROCK_STAGES]; ROSENBROCK_STAGES];
        for j in 0..n {
            for i in j..n {
                let identity = if i == j { 1.0 } else { 0.0 };
                let sum: f64 = (j..i).map(|k| gamma(i, k) * inverse[k][j]).sum();
                inverse[i][j] = (identity - sum) / self.gamma;
            }
        }
        let mut stages = RosenbrockStages { stages: n, gamma: self.gamma, ..Default::default() };
        for i in 0..n {
            stages.nodes[i] = self.alpha[i].iter().sum();
            for j in 0..i {
                stages.a[i][j] = (j..i).map(|k| self.alpha[i][k] * inverse[k][j]).sum();
                stages.c[i][j] = -inverse[i][j];
            }
        }
        for j in 0..n {
            stages.m[j] = (j..n).map(|k| self.b[k] * inverse[k][j]).sum();
            stages.e[j] = (j..n).map(|k| (self.b[k] - self.b_hat[k]) * inverse[k][j]).sum();
        }
        stages
    }
}

// ROS34PW2's coefficients, with the digits Rang and Angermann publish.
#[allow(clippy::excessive_precision)]
mod ros34pw2 {
    pub const GAMMA: f64 = 4.3586652150845900e-01;
    pub const ALPHA: [&[f64]; 4] =
        [&[], &[8.7173304301691801e-01], &[8.4457060015369423e-01, -1.1299064236484185e-01], &[0.0, 0.0, 1.0]];
    pub const GAMMA_BELOW: [&[f64]; 4] = [
        &[],
        &[-8.7173304301691801e-01],
        &[-9.0338057013044082e-01, 5.4180672388095326e-02],
        &[2.4212380706095346e-01, -1.2232505839045147e+00, 5.4526025533510214e-01],
    ];
    pub const B: [f64; 4] = [2.4212380706095346e-01, -1.2232505839045147e+00, 1.5452602553351020e+00, GAMMA];
    pub const B_HAT: [f64; 4] =
        [3.7810903145819369e-01, -9.6042292212423178e-02, 5.0000000000000000e-01, 2.1793326075422950e-01];
}

/// The share of the tolerance one ROS34PW2 step may take.
pub const ROS34PW2_SHARE: f64 = 1.0 / 80.0;

/// ROS34PW2 (Rang & Angermann, BIT 45, 2005): a Rosenbrock–W method with 4
/// stages and 4 evaluations of f, order 3 for any W, an embedded order-2
/// estimate, L-stable and stiffly accurate (its solution is its last
/// stage's argument plus that stage's u, so stiff components are damped,
/// never amplified, at any h).
pub const ROS34PW2: Rosenbrock = Rosenbrock {
    gamma: ros34pw2::GAMMA,
    alpha: &ros34pw2::ALPHA,
    gamma_below: &ros34pw2::GAMMA_BELOW,
    b: &ros34pw2::B,
    b_hat: &ros34pw2::B_HAT,
    // The trapezoid rule between the step's start and stage 4 (at t + h,
    // at the solution up to that stage's u): no stage point is more exact.
    power_weights: &[0.5, 0.0, 0.0, 0.5],
    // Held per step, as stiff solvers hold theirs: its estimate is the
    // order-2 solution's error, O(h³), so per unit step (O(h²) ≤ tol) a
    // vehicle's fast, damped transient holds the step to nanoseconds (on
    // the damped stiff boom of docs/integration.md). Per step, the order-3
    // solution it propagates errs by O(h⁴), so the global error, O(h³), is
    // proportional to the tolerance; the share puts it within the band of
    // the adaptive methods on the random trees of tests/all/adaptive_integration.rs
    // (measured 0.8–10 times the tolerance; 1/40, calibrated while W was
    // formed afresh at each advance, gave up to 31 times once W is kept
    // across advances, 1/60 up to 16; docs/integration.md, "Stiff vehicles").
    control: StepControl {
        order: 3,
        controller_exponent: 1.0 / 3.0,
        factor_bounds: (0.2, 6.0),
        error_per: ErrorPer::Step { share: ROS34PW2_SHARE },
        order_gap_anchor: None,
    },
};

/// The order-gap anchor of the 5th-order pairs with a 4th-order estimate
/// (`dopri5`, `tsit5`): their errors fell as tol^0.25, and on the 1 s
/// fixtures from 0.04–0.2 of the tolerance at 1e-4 to 0.007–0.06 at 1e-8;
/// the 10 s random trees delivered up to 23 at 1e-5 (tree 3) and 6.9 at
/// 1e-6, so the discount starts there: below it they keep 0.35–6.3, the
/// fixtures 0.02–0.39.
const FIFTH_ORDER_GAP_ANCHOR: f64 = 1e-6;

/// How a method forms a step.
#[derive(Clone, Copy, Debug)]
pub enum Scheme {
    /// Explicit Runge–Kutta stages.
    Explicit(&'static Tableau),
    /// Linearly implicit stages with the Jacobian of the rates.
    Rosenbrock(&'static Rosenbrock),
}

/// The integration methods, as the FMU's `method` parameter names them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Method {
    /// Classical RK4 with fixed internal steps of at most `max_step`.
    Rk4,
    /// Dormand–Prince 5(4), adaptive.
    Dopri5,
    /// Dormand–Prince 8(5,3), adaptive.
    Dop853,
    /// ROS34PW2, an L-stable Rosenbrock–W method of order 3, adaptive.
    Ros34pw2,
    /// Bogacki–Shampine 3(2), adaptive.
    Bs3,
    /// Tsitouras 5(4), adaptive.
    Tsit5,
}

impl Method {
    /// Every method, in the order of the FMU's enumeration (values 1 to 6:
    /// new methods are appended, so that a value keeps naming its method).
    pub const ALL: [Method; 6] =
        [Method::Rk4, Method::Dopri5, Method::Dop853, Method::Ros34pw2, Method::Bs3, Method::Tsit5];

    /// How it forms a step.
    pub fn scheme(self) -> Scheme {
        match self {
            Method::Rk4 => Scheme::Explicit(&RK4),
            Method::Dopri5 => Scheme::Explicit(&DOPRI5),
            Method::Dop853 => Scheme::Explicit(&DOP853),
            Method::Ros34pw2 => Scheme::Rosenbrock(&ROS34PW2),
            Method::Bs3 => Scheme::Explicit(&BS3),
            Method::Tsit5 => Scheme::Explicit(&TSIT5),
        }
    }

    /// Its order and step-size controller.
    pub fn control(self) -> &'static StepControl {
        match self.scheme() {
            Scheme::Explicit(tableau) => &tableau.control,
            Scheme::Rosenbrock(method) => &method.control,
        }
    }

    /// The number of stages of a step.
    pub fn stages(self) -> usize {
        match self.scheme() {
            Scheme::Explicit(tableau) => tableau.b.len(),
            Scheme::Rosenbrock(method) => method.b.len(),
        }
    }

    /// Its name, as in the FMU's enumeration and the CLI.
    pub fn name(self) -> &'static str {
        match self {
            Method::Rk4 => "rk4",
            Method::Dopri5 => "dopri5",
            Method::Dop853 => "dop853",
            Method::Ros34pw2 => "ros34pw2",
            Method::Bs3 => "bs3",
            Method::Tsit5 => "tsit5",
        }
    }

    /// One line for people.
    pub fn description(self) -> &'static str {
        match self {
            Method::Rk4 => "classical 4th-order Runge-Kutta, fixed internal step max_step",
            Method::Dopri5 => "Dormand-Prince 5(4), adaptive to tolerance, steps at most max_step",
            Method::Dop853 => "Dormand-Prince 8(5,3), adaptive to tolerance, steps at most max_step",
            Method::Ros34pw2 => {
                "ROS34PW2, L-stable Rosenbrock-W of order 3 for stiff vehicles (Jacobian by finite differences), \
                 adaptive to tolerance, steps at most max_step"
            }
            Method::Bs3 => "Bogacki-Shampine 3(2), adaptive to tolerance, steps at most max_step",
            Method::Tsit5 => "Tsitouras 5(4), adaptive to tolerance, steps at most max_step",
        }
    }

    /// The method of a name.
    pub fn from_name(name: &str) -> Option<Method> {
        Method::ALL.into_iter().find(|m| m.name() == name)
    }

    /// Its continuous extension, if it has one (explicit pairs; not RK4 or ROS34PW2).
    pub fn dense(self) -> Option<&'static DenseOutput> {
        match self.scheme() {
            Scheme::Explicit(tableau) => tableau.dense,
            Scheme::Rosenbrock(_) => None,
        }
    }

    /// Its stability boundary on the negative real axis: the largest x
    /// with |R(−x)| ≤ 1, so that a step of h·|λ| ≤ x does not amplify a
    /// damped mode of rate λ < 0. Where the vehicle has a fast, strongly
    /// damped mode, this and not the tolerance holds an explicit method's
    /// steps (h ≈ x / |λ|). None for ROS34PW2, which is L-stable.
    /// (`stability_bounds_on_the_negative_real_axis` checks the values.)
    pub fn real_stability_bound(self) -> Option<f64> {
        match self {
            Method::Rk4 => Some(2.7853),
            Method::Dopri5 => Some(3.3066),
            Method::Dop853 => Some(6.3936),
            Method::Bs3 => Some(2.5127),
            Method::Tsit5 => Some(3.5068),
            Method::Ros34pw2 => None,
        }
    }

    /// Where, as a share of the step, an explicit method with a dense
    /// output reads the constraint margins besides its stages: the middle of
    /// the widest gap between its nodes (with 0 and 1), where that gap is
    /// more than a fifth of the step (switches.rs): 0.6135 for `tsit5`,
    /// 0.55 for `dopri5`, 0.25 for `bs3`, 0.467 for `dop853` (1/3 → 0.6).
    pub fn gap_probe(self) -> Option<f64> {
        let Scheme::Explicit(tableau) = self.scheme() else { return None };
        tableau.dense?;
        let nodes = || tableau.c.iter().copied().chain([1.0]);
        // Each node's gap to the next one up (a dozen nodes at most).
        let (width, middle) = nodes()
            .filter_map(|low| {
                let high = nodes().filter(|&c| c > low).fold(f64::INFINITY, f64::min);
                high.is_finite().then_some((high - low, 0.5 * (low + high)))
            })
            .fold((0.0, 0.0), |widest, gap| if gap.0 > widest.0 { gap } else { widest });
        (width > 0.2).then_some(middle)
    }

    /// Whether it adapts its step to a tolerance.
    pub fn is_adaptive(self) -> bool {
        match self.scheme() {
            Scheme::Explicit(tableau) => !matches!(tableau.error, ErrorEstimate::None),
            Scheme::Rosenbrock(_) => true,
        }
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Complex;

    use super::*;

    /// The gap probes, against the nodes as published: Tsitouras' 0.161,
    /// 0.327, 0.9, 0.98, 1 (widest 0.327 → 0.9), Dormand–Prince's 1/5,
    /// 3/10, 4/5, 8/9, 1 (3/10 → 4/5), Bogacki–Shampine's 1/2, 3/4, 1
    /// (0 → 1/2), DOP853's (its 12 nodes) 1/3 → 0.6.
    #[test]
    fn the_gap_probe_is_the_middle_of_the_widest_gap_between_nodes() {
        let probe = |method: Method| method.gap_probe().map(|share| (share * 1e6).round() / 1e6);
        assert_eq!(probe(Method::Tsit5), Some(0.6135));
        assert_eq!(probe(Method::Dopri5), Some(0.55));
        assert_eq!(probe(Method::Bs3), Some(0.25));
        assert_eq!(probe(Method::Dop853), Some(0.466667));
        assert_eq!(probe(Method::Rk4), None);
        assert_eq!(probe(Method::Ros34pw2), None);
    }

    /// The nested form's slope, against central differences of its value.
    #[test]
    fn the_nested_slope_is_the_derivative_of_the_nested_form() {
        let rows = [0.7, -1.3, 2.1, 0.4, -0.9, 1.6, -0.2];
        for n in 1..=rows.len() {
            for s in [0.0, 0.1, 0.5, 0.83, 1.0] {
                let h = 1e-6;
                let value = |s: f64| nested(s, n, |j| rows[j]);
                let differenced = (value(s + h) - value(s - h)) / (2.0 * h);
                let slope = nested_slope(s, n, |j| rows[j]);
                assert!((slope - differenced).abs() < 1e-8, "{n} rows at {s}: {slope} against {differenced}");
            }
        }
    }

    /// Row sums of a equal c, and the weights of the solution and of every
    /// estimator sum to 1 and 0: the first consistency conditions, which
    /// catch a mistyped coefficient in most rows.
    #[test]
    fn tableaus_are_consistent() {
        for method in Method::ALL {
            let Scheme::Explicit(t) = method.scheme() else { continue };
            assert_eq!(t.a.len(), t.b.len());
            assert_eq!(t.c.len(), t.b.len());
            for (i, row) in t.a.iter().enumerate() {
                assert_eq!(row.len(), i);
                let sum: f64 = row.iter().sum();
                assert!((sum - t.c[i]).abs() < 1e-14, "{method:?} row {i}: {sum} vs c = {}", t.c[i]);
            }
            assert!((t.b.iter().sum::<f64>() - 1.0).abs() < 1e-14, "{method:?}");
            let estimators: Vec<&[f64]> = match t.error {
                ErrorEstimate::None => vec![],
                ErrorEstimate::Embedded(e) => vec![e],
                ErrorEstimate::Dop853 { fifth, third } => vec![fifth, third],
            };
            for e in estimators {
                assert_eq!(e.len(), t.b.len());
                assert!(e.iter().sum::<f64>().abs() < 1e-14, "{method:?}");
            }
            // Second-order condition Σ bᵢcᵢ = ½.
            let bc: f64 = t.b.iter().zip(t.c).map(|(b, c)| b * c).sum();
            assert!((bc - 0.5).abs() < 1e-14, "{method:?}: {bc}");
        }
    }

    /// A rooted tree, as the trees hanging from its root (in canonical order).
    #[derive(Clone, Debug, PartialEq)]
    struct Tree(Vec<Tree>);

    impl Tree {
        fn order(&self) -> usize {
            1 + self.0.iter().map(Tree::order).sum::<usize>()
        }

        /// γ(t) = |t| Π γ(children): the exact solution's coefficient is 1/γ.
        fn density(&self) -> f64 {
            self.order() as f64 * self.0.iter().map(Tree::density).product::<f64>()
        }

        /// Φᵢ(t) per stage i = Π over children u of Σⱼ aᵢⱼ Φⱼ(u): the
        /// elementary weights, whose b-weighted sum must be 1/γ(t).
        fn weights(&self, a: &[&[f64]]) -> Vec<f64> {
            let mut product = vec![1.0; a.len()];
            for child in &self.0 {
                let inner = child.weights(a);
                for (i, row) in a.iter().enumerate() {
                    product[i] *= row.iter().zip(&inner).map(|(a, phi)| a * phi).sum::<f64>();
                }
            }
            product
        }
    }

    /// Every rooted tree of order 1 to `highest`, each once: a root with a
    /// multiset of smaller trees, taken in non-increasing index order.
    fn rooted_trees(highest: usize) -> Vec<Tree> {
        fn children(all: &[Tree], left: usize, below: usize, chosen: &mut Vec<Tree>, out: &mut Vec<Tree>) {
            if left == 0 {
                out.push(Tree(chosen.clone()));
                return;
            }
            for index in 0..below {
                if all[index].order() <= left {
                    chosen.push(all[index].clone());
                    children(all, left - all[index].order(), index + 1, chosen, out);
                    chosen.pop();
                }
            }
        }
        let mut all = Vec::new();
        for order in 1..=highest {
            let mut new = Vec::new();
            children(&all, order - 1, all.len(), &mut Vec::new(), &mut new);
            all.extend(new);
        }
        all
    }

    /// The largest |Σ wᵢΦᵢ(t) − 1/γ(t)| over the trees of exactly `order`.
    fn order_defect(a: &[&[f64]], w: &[f64], trees: &[Tree], order: usize) -> f64 {
        trees
            .iter()
            .filter(|t| t.order() == order)
            .map(|t| (t.weights(a).iter().zip(w).map(|(phi, w)| phi * w).sum::<f64>() - 1.0 / t.density()).abs())
            .fold(0.0, f64::max)
    }

    /// Every explicit method's solution satisfies all the order conditions
    /// (one per rooted tree: 200 up to order 8) of its order and misses one
    /// of the next, and every embedded solution (b minus an estimator's
    /// weights) those of its own order: a mistyped coefficient of a, b or
    /// an estimator breaks some condition by far more than round-off.
    #[test]
    fn tableaus_satisfy_their_order_conditions() {
        let trees = rooted_trees(9);
        let count = |order| trees.iter().filter(|t| t.order() == order).count();
        assert_eq!((1..=9).map(count).collect::<Vec<_>>(), [1, 1, 2, 4, 9, 20, 48, 115, 286]);
        for method in Method::ALL {
            let Scheme::Explicit(t) = method.scheme() else { continue };
            let order = t.control.order as usize;
            for k in 1..=order {
                let defect = order_defect(t.a, t.b, &trees, k);
                assert!(defect < 1e-13, "{method:?}: order-{k} conditions off by {defect:e}");
            }
            let next = order_defect(t.a, t.b, &trees, order + 1);
            assert!(next > 1e-6, "{method:?} is of order {} as well ({next:e})", order + 1);
            let embedded: Vec<(&[f64], usize)> = match t.error {
                ErrorEstimate::None => vec![],
                ErrorEstimate::Embedded(e) => vec![(e, order - 1)],
                ErrorEstimate::Dop853 { fifth, third } => vec![(fifth, 5), (third, 3)],
            };
            for (e, embedded_order) in embedded {
                let b_hat: Vec<f64> = t.b.iter().zip(e).map(|(b, e)| b - e).collect();
                for k in 1..=embedded_order {
                    let defect = order_defect(t.a, &b_hat, &trees, k);
                    assert!(defect < 1e-13, "{method:?}: order-{embedded_order} estimate off by {defect:e} at {k}");
                }
            }
        }
    }

    /// A method's stages and its dense output's extra stages, as one tableau's rows of a.
    fn extended_rows(t: &Tableau, dense: &DenseOutput) -> Vec<Vec<f64>> {
        let mut rows: Vec<Vec<f64>> = t.a.iter().map(|row| row.to_vec()).collect();
        rows.extend(dense.extra.iter().map(|(_, row)| row.to_vec()));
        let stages = rows.len();
        rows.iter_mut().for_each(|row| row.resize(stages, 0.0));
        rows
    }

    /// Every dense output satisfies the order conditions of its order at
    /// every point of the step: Σ Bᵢ(s)Φᵢ(t) = s^|t|/γ(t) for every rooted
    /// tree t up to that order (85 up to DOP853's 7), with the extra
    /// stages' rows summing to their nodes; at s = 1 it is the step's
    /// result. A coefficient mistyped in its 11th digit breaks one of them.
    #[test]
    fn dense_outputs_satisfy_their_order_conditions() {
        let trees = rooted_trees(7);
        for method in Method::ALL {
            let Scheme::Explicit(t) = method.scheme() else { continue };
            let Some(dense) = t.dense else { continue };
            let rows = extended_rows(t, dense);
            for ((c, _), row) in dense.extra.iter().zip(&rows[t.b.len()..]) {
                assert!((row.iter().sum::<f64>() - c).abs() < 1e-14, "{method:?}: an extra stage's row sum");
            }
            let a: Vec<&[f64]> = rows.iter().map(|row| &row[..]).collect();
            for s in [0.1, 0.37, 0.5, 0.81, 1.0] {
                let weights: Vec<f64> =
                    (0..rows.len()).map(|i| nested(s, dense.rows(), |j| dense.weight(t.b, j, i))).collect();
                for tree in trees.iter().filter(|tree| tree.order() <= dense.order as usize) {
                    let sum: f64 = tree.weights(&a).iter().zip(&weights).map(|(phi, w)| phi * w).sum();
                    let exact = s.powi(tree.order() as i32) / tree.density();
                    assert!(
                        (sum - exact).abs() < 1e-13,
                        "{method:?} at s = {s}, order {}: {sum} vs {exact}",
                        tree.order()
                    );
                }
                if s == 1.0 {
                    for (i, w) in weights.iter().enumerate() {
                        let b = t.b.get(i).copied().unwrap_or(0.0);
                        assert!((w - b).abs() < 1e-13, "{method:?}: Bᵢ(1) = {w} at stage {i}, b = {b}");
                    }
                }
            }
        }
    }

    /// Tsitouras gives his interpolant as bᵢ(s) = rᵢ₁s + rᵢ₂s² + rᵢ₃s³ + rᵢ₄s⁴;
    /// the nested form with his rᵢ₄ alone as the correction gives his rᵢ₂
    /// and rᵢ₃ too (the published digits, to their last).
    #[test]
    fn tsit5_dense_output_is_the_published_polynomial() {
        let published: [[f64; 2]; 7] = [
            [-2.763706197274826, 2.9132554618219126],
            [0.13169999999999998, -0.2234],
            [3.9302962368947516, -5.941033872131505],
            [-12.411077166933676, 30.33818863028232],
            [37.50931341651104, -88.1789048947664],
            [-27.896526289197286, 65.09189467479366],
            [1.5, -4.0],
        ];
        let dense = TSIT5.dense.unwrap();
        for (i, [r2, r3]) in published.iter().enumerate() {
            let r4 = tsit5::DENSE[i];
            let r1 = if i == 0 { 1.0 } else { 0.0 };
            for s in [0.25, 0.5, 0.9] {
                let polynomial = r1 * s + r2 * s * s + r3 * s.powi(3) + r4 * s.powi(4);
                let ours = nested(s, dense.rows(), |j| dense.weight(TSIT5.b, j, i));
                assert!((ours - polynomial).abs() < 1e-14, "stage {i} at {s}: {ours} vs {polynomial}");
            }
        }
    }

    /// |R(iy)| of a tableau on y' = λy with hλ = iy: the amplification of an
    /// undamped oscillation of frequency ω by one step h = y/ω.
    fn amplification(t: &Tableau, y: f64) -> f64 {
        amplification_at(t, Complex::new(0.0, y))
    }

    /// |R(z)| of a tableau on y' = λy with hλ = z.
    fn amplification_at(t: &Tableau, z: Complex<f64>) -> f64 {
        let mut stages: Vec<Complex<f64>> = Vec::with_capacity(t.b.len());
        for row in t.a {
            let sum: Complex<f64> = row.iter().zip(&stages).map(|(a, s)| s * *a).sum();
            stages.push(Complex::new(1.0, 0.0) + z * sum);
        }
        let weighted: Complex<f64> = t.b.iter().zip(&stages).map(|(b, s)| s * *b).sum();
        (Complex::new(1.0, 0.0) + z * weighted).norm()
    }

    /// The largest h·ω below which a method does not amplify an undamped
    /// oscillation: what limits explicit steps on a stiff, undamped mode
    /// (docs/integration.md, "Stiff vehicles"). RK4's is 2√2 exactly, which
    /// checks the scan. DOPRI5 is stable only up to about 1, and beyond it
    /// amplifies slowly at first (by 1.4e-6 per step at 1, 3 % at 2).
    #[test]
    fn stability_bounds_on_the_imaginary_axis() {
        let bound = |t: &Tableau| {
            let mut y = 0.0;
            while amplification(t, y + 1e-4) <= 1.0 + 1e-12 {
                y += 1e-4;
            }
            y
        };
        let rk4 = bound(&RK4);
        assert!((rk4 - 2.0 * 2f64.sqrt()).abs() < 2e-4, "{rk4}");
        let dop853 = bound(&DOP853);
        assert!(dop853 > rk4, "DOP853 stable up to {dop853}");
        let dopri5 = bound(&DOPRI5);
        assert!(dopri5 > 0.5, "DOPRI5 stable up to {dopri5}");
        let growth = |y| amplification(&DOPRI5, y) - 1.0;
        println!(
            "h·ω bounds: rk4 {rk4:.2}, dop853 {dop853:.2}, dopri5 {dopri5:.2} (|R| − 1 at 1, 2, 3: {:.1e}, {:.1e}, {:.1e})",
            growth(1.0),
            growth(2.0),
            growth(3.0)
        );
    }

    /// The explicit methods' stability boundaries on the negative real axis,
    /// as `Method::real_stability_bound` states them, from a scan of the
    /// tableaus (RK4's is the root of 1 − x + x²/2 − x³/6 + x⁴/24 = 1, 2.7853).
    #[test]
    fn stability_bounds_on_the_negative_real_axis() {
        for method in Method::ALL {
            let (Scheme::Explicit(tableau), Some(stated)) = (method.scheme(), method.real_stability_bound()) else {
                assert!(method.real_stability_bound().is_none(), "{method:?}");
                continue;
            };
            let mut x = 0.0;
            while amplification_at(tableau, Complex::new(-(x + 1e-4), 0.0)) <= 1.0 + 1e-12 {
                x += 1e-4;
            }
            println!("{}: {x:.4}", method.name());
            assert!((x - stated).abs() < 2e-3 * stated, "{method:?}: scanned {x}, stated {stated}");
        }
    }

    /// R(z, w) of a Rosenbrock–W method on y' = λy with z = hλ, run with
    /// W = μ, w = hμ (the Jacobian when w = z), from its stage form.
    fn rosenbrock_amplification(stages: &RosenbrockStages, z: Complex<f64>, w: Complex<f64>) -> Complex<f64> {
        let (one, gamma_inverse) = (Complex::new(1.0, 0.0), 1.0 / stages.gamma);
        let mut u: Vec<Complex<f64>> = Vec::new();
        for i in 0..stages.stages {
            let argument = one + (0..i).map(|j| u[j] * stages.a[i][j]).sum::<Complex<f64>>();
            let rhs = z * argument + (0..i).map(|j| u[j] * stages.c[i][j]).sum::<Complex<f64>>();
            u.push(rhs / (gamma_inverse - w));
        }
        one + (0..stages.stages).map(|i| u[i] * stages.m[i]).sum::<Complex<f64>>()
    }

    /// ROS34PW2's published coefficients, through the stage form, give
    /// order 3 on the test equation with W the Jacobian and with W far
    /// from it (the error of R against eᶻ falls 16-fold as h halves), an
    /// order-2 estimate, and L-stability: |R| ≤ 1 on the imaginary axis
    /// and R → 0 at −∞, so a stiff mode is damped at any step.
    #[test]
    fn ros34pw2_is_third_order_for_any_w_and_l_stable() {
        let stages = ROS34PW2.stages();
        let lambda = Complex::new(1.0, 0.0);
        for mu in [lambda, Complex::new(-3.0, 0.5), Complex::new(0.0, 0.0)] {
            let error = |h: f64| (rosenbrock_amplification(&stages, lambda * h, mu * h) - h.exp()).norm();
            let ratio = error(0.02) / error(0.01);
            assert!((14.0..18.0).contains(&ratio), "W = {mu}: error ratio {ratio}, 16 for order 3");
        }
        for y in (0..2000).map(|k| 10f64.powf(-2.0 + k as f64 * 0.004)) {
            let z = Complex::new(0.0, y);
            let r = rosenbrock_amplification(&stages, z, z).norm();
            assert!(r <= 1.0 + 1e-12, "|R({y}i)| = {r}");
        }
        for x in [1e4, 1e8, 1e12] {
            let z = Complex::new(-x, 0.0);
            let r = rosenbrock_amplification(&stages, z, z).norm();
            assert!(r < 10.0 / x, "|R(−{x})| = {r}");
        }
        let low = RosenbrockStages { m: std::array::from_fn(|i| stages.m[i] - stages.e[i]), ..stages };
        let estimate = |h: f64| {
            let z = lambda * h;
            (rosenbrock_amplification(&stages, z, z) - rosenbrock_amplification(&low, z, z)).norm()
        };
        let ratio = estimate(0.02) / estimate(0.01);
        assert!((7.0..9.0).contains(&ratio), "estimate ratio {ratio}, 8 for an order-2 estimate");
    }

    #[test]
    fn names_round_trip() {
        for method in Method::ALL {
            assert_eq!(Method::from_name(method.name()), Some(method));
        }
        assert_eq!(Method::from_name("euler"), None);
    }
}
