"""Names of the ami_xr data model: dimensions, variables and attributes.

Every module imports its names from here so that a dimension or attribute is spelled in exactly
one place. The README's "Data model" section documents the same names for users.
"""

from __future__ import annotations

# --- dimensions -------------------------------------------------------------------------------
POINT = "point"  # response point (measurement degree of freedom)
FREQUENCY = "frequency"  # frequency in Hz
TIME = "time"  # time in seconds
RECORD = "record"  # repeated hits or blocks of a time record
# excitation location of multi-reference FRFs (a reference on a point is its drive point)
REFERENCE = "reference"
MODE = "mode"  # identified or exact system mode
COMPLEX = "complex"  # on-disk only: trailing dim of length 2 holding (real, imag)

# --- variables --------------------------------------------------------------------------------
FRF = "frf"  # complex FRF, dims (point, frequency)
RESPONSE = "response"  # response time histories, dims ([record,] point, time)
FORCE = "force"  # force time histories, dims ([record,] [reference,] time)
COHERENCE = "coherence"  # ordinary (or multiple) coherence, dims (point, frequency)
# Optional measurement geometry: non-dimension float coordinates on ``point`` with a units attr
POINT_X = "point_x"
POINT_Y = "point_y"
POINT_Z = "point_z"
POINT_COORDS = (POINT_X, POINT_Y, POINT_Z)
COORDINATE_UNITS = "m"  # default units of point_x/y/z (make_frf_dataset(coordinates=...))

# --- attributes -------------------------------------------------------------------------------
ATTR_DRIVE_POINT = "drive_point"  # label of the point where the force acts (the paper's P)
ATTR_DRIVE_POINT_ASSUMED = "drive_point_assumed"  # why the drive point was assumed (not given)
ATTR_QUANTITY = "response_quantity"  # "displacement" | "velocity" | "acceleration"
ATTR_FRF_TYPE = "frf_type"  # "receptance" | "mobility" | "accelerance" (follows the quantity)
ATTR_UNITS = "units"  # on variables and coordinates
ATTR_RESPONSE_UNITS = "response_units"  # e.g. "m", "m/s", "m/s^2"
ATTR_FORCE_UNITS = "force_units"  # e.g. "N"
ATTR_SOURCE = "frf_source"  # how the FRF was made, see SOURCES
ATTR_DT = "sample_interval"  # s, for FRFs made from sampled impulse responses
ATTR_NSAMPLES = "record_samples"  # number of time samples the FFT used
ATTR_EXP_DECAY = "exponential_window_decay"  # 1/s, decay rate an exponential window added
ATTR_HISTORY = "ami_xr_history"  # provenance: JSON list of {function, parameters, time, ...}
ATTR_VERSION = "ami_xr_version"
ATTR_FUNCTION = "ami_xr_function"  # provenance: the function of the latest history record
ATTR_SOURCE_FILE = "source_file"
ATTR_EXCITATION = "excitation"  # on time Datasets: "unit_impulse" when there is no force record
EXCITATION_UNIT_IMPULSE = "unit_impulse"

# --- allowed values ---------------------------------------------------------------------------
QUANTITY_TO_FRF_TYPE = {
    "displacement": "receptance",
    "velocity": "mobility",
    "acceleration": "accelerance",
}
FRF_TYPE_TO_QUANTITY = {v: k for k, v in QUANTITY_TO_FRF_TYPE.items()}
# derivative order k of each response quantity: its FRF is (i w)^k times the receptance
QUANTITY_POWER = {"displacement": 0, "velocity": 1, "acceleration": 2}

SOURCE_IMPULSE = "impulse_response"  # FRF = dt * FFT(sampled impulse response)
SOURCE_ANALYTIC = "analytic"  # FRF evaluated from the continuous-time model (eq. 4)
SOURCE_ESTIMATED = "estimated"  # H1/H2/Hv estimate from force and response histories
SOURCE_MEASURED = "measured"  # imported from another tool; origin unknown
SOURCES = (SOURCE_IMPULSE, SOURCE_ANALYTIC, SOURCE_ESTIMATED, SOURCE_MEASURED)

RESPONSE_UNITS = {
    "displacement": ("m", "mm", "um", "in"),
    "velocity": ("m/s", "mm/s", "in/s"),
    "acceleration": ("m/s^2", "mm/s^2", "g", "in/s^2"),
}
SI_RESPONSE_UNITS = {"displacement": "m", "velocity": "m/s", "acceleration": "m/s^2"}
FORCE_UNITS = ("N", "kN", "lbf")
FREQUENCY_UNITS = "Hz"
TIME_UNITS = "s"
ANGULAR_UNITS = "rad/s"  # eigenvalues; residues are FRF units times rad/s
DIMENSIONLESS_UNITS = "1"  # damping ratios
ATTR_LONG_NAME = "long_name"  # CF description of a variable


def frf_units(response_units: str, force_units: str) -> str:
    """Units string of an FRF, e.g. ``"m/N"`` for receptance in metres per newton."""
    return f"{response_units}/{force_units}"


# --- modal results (identification outputs and simulator truth use the same names) ------------
EIGENVALUE = "eigenvalue"  # complex, rad/s, upper half plane: -zeta*wn + i*wd
NATURAL_FREQUENCY = "natural_frequency"  # Hz, |lambda| / (2 pi)
DAMPING_RATIO = "damping_ratio"  # -Re(lambda) / |lambda|
RESIDUE = "residue"  # complex A1 + i*A2 of eq. 4, dims (point, mode)
MODE_VECTOR = "mode_vector"  # complex Phi of eq. 8, dims (point, mode)
MODE_VECTOR_NORMALISED = "mode_vector_normalised"  # Phi rotated and scaled: largest entry 1
MPC = "mpc"  # modal phase collinearity (Pappa et al. 1993), 0..1, dims (mode)
MPD = "mpd"  # mean phase deviation from the best line through 0, degrees, dims (mode)
COMPLEXITY = "complexity"  # mode complexity 1 - MPC, 0 (real mode) .. 1, dims (mode)

# --- joint refinement (ami_xr.refine) and Cramér-Rao bound (ami_xr.cramer_rao_bound) ---------
AMI_PREFIX = "ami_"  # refine keeps the AMI values as ami_eigenvalue, ami_residue, ...
EIGENVALUE_STD = "eigenvalue_std"  # complex: std(Re lam) + i std(Im lam), rad/s
NATURAL_FREQUENCY_STD = "natural_frequency_std"  # Hz
DAMPING_RATIO_STD = "damping_ratio_std"  # absolute (not %)
RESIDUE_STD = "residue_std"  # sqrt(E|dA|^2), dims (point, mode)
MODE_VECTOR_STD = "mode_vector_std"  # sqrt(E|dPhi|^2), dims (point, mode)
# sqrt(E|noise|^2) of one FRF line, one level per FRF: dims (point), refine's output
FRF_NOISE_STD = "frf_noise_std"
# the same per line, beside frf in an FRF Dataset: dims ([reference,] point, frequency), attr
# ATTR_NOISE_MODEL (ami_xr.frf / impact_frf from coherence, or ami_xr.dsp.noise_model)
FRF_LINE_NOISE_STD = "frf_line_noise_std"
# on frf_line_noise_std: how it was estimated (formula, n_d, window)
ATTR_NOISE_MODEL = "noise_model"
NATURAL_FREQUENCY_ERROR = "natural_frequency_error"  # CRB: expected |error| / f_n
DAMPING_RATIO_ERROR = "damping_ratio_error"  # CRB: expected |error| / zeta
MODE_VECTOR_ERROR = "mode_vector_error"  # CRB: expected |dPhi_k| / |Phi_k| (Euclidean norms)
# quality flags of a mode (bits of QUALITY_FLAGS); their text joins them by FLAG_SEPARATOR
FLAG_SEPARATOR = ","
FLAG_LOW_DRIVE_SNR = "low_drive_point_snr"  # global_fit: scale unreliable (weak at the drive point)
FLAG_UNSCALED = "unscaled_no_drive_point"  # global_fit: mode vector normalised, not scaled
FLAG_NOT_CONVERGED = "not_converged"  # isolation did not converge where the mode was detected
FLAG_SINGLE_FRF = "single_frf"  # detected in one FRF only
FLAG_REFINE_NOT_CONVERGED = "refine_not_converged"
FLAG_REFINE_FALLBACK = "refine_fallback"
FLAG_ADDED_BY_REFINE = "added_by_refine"  # a mode refine added
# half-power bandwidth 2 zeta f_n under 3 lines of the FRF (ami_xr.ami.resolution)
FLAG_UNDER_RESOLVED = "under_resolved"

# --- FRF estimation from time histories (ami_xr.frf) ------------------------------------------
FORCE_AUTOSPECTRUM = "force_autospectrum"  # Gff, one-sided density, dims ([reference,] frequency)
RESPONSE_AUTOSPECTRUM = "response_autospectrum"  # Gyy, dims (point, frequency)
# Gfy = E[conj(F) Y], complex, dims ([reference,] point, frequency)
CROSS_SPECTRUM = "cross_spectrum"
HIT_REJECTED = "hit_rejected"  # bool, dims (record): impact hit left out of the average
HIT_REJECT_REASON = "hit_reject_reason"  # str, dims (record): why ("" when accepted)
HIT_PEAK_FORCE = "hit_peak_force"  # largest |force| of each hit, dims (record)
RECORD_START = "record_start"  # s, start time of each record (e.g. LVM segment X0), dims (record)
ATTR_ESTIMATOR = "estimator"  # "H1" | "H2" | "Hv"
ATTR_N_AVERAGES = "n_averages"  # number of segments (hits) averaged
ATTR_FORCE_WINDOW_WIDTH = "force_window_width"  # s, width of the force (transient) window

# --- AMI phases (ami_xr.ami: subtract, isolate, global_fit, identify) -------------------------
CANDIDATE = "candidate"  # dim: candidate modes of one FRF found by the Subtraction Phase
MODE_2 = "mode_2"  # second mode dim of the MAC matrix
RESIDUAL_TERM = "residual_term"  # dim: RESIDUAL_TERM_LABELS, residual terms of the global fit
RESIDUAL_TERM_LABELS = ("lower", "upper")  # coordinate of RESIDUAL_TERM (and its order)
SUB_EIGENVALUE = "subtraction_eigenvalue"  # (point, candidate) complex rad/s
SUB_RESIDUE = "subtraction_residue"  # (point, candidate) complex
SUB_BAND_LOW = "subtraction_band_low"  # (point, candidate) Hz, first line of the fit band
SUB_BAND_HIGH = "subtraction_band_high"  # (point, candidate) Hz, last line of the fit band
SUB_NOISE_FLOOR = "subtraction_noise_floor"  # (point) noise standard deviation, FRF units
SUB_STOP_STATISTIC = "subtraction_stop_statistic"  # (point) |Y|^2/sigma^2 of the last peak
SUB_STOP_REASON = "subtraction_stop_reason"  # (point) str
SUB_N_MODES = "subtraction_n_modes"  # (point) int
DETECTED = "detected"  # (point, mode) bool: the paper's Tables 1-2 (False = its x mark)
POINT_EIGENVALUE = "point_eigenvalue"  # (point, mode) complex, NaN where not detected
POINT_SNR = "point_snr"  # (point, mode) peak |contribution| / noise floor
EIGENVALUE_SPREAD = "eigenvalue_spread"  # (mode) complex: std(Re) + i std(Im) across FRFs
ISO_ITERATIONS = "isolation_iterations"  # (point) int
ISO_CONVERGED = "isolation_converged"  # (point) bool
FRF_SYNTHESIZED = "frf_synthesized"  # (point, frequency) complex model of the global fit
FRF_RESIDUAL = "frf_residual"  # (point, frequency) complex frf - frf_synthesized
RESIDUAL_COEFFICIENT = "residual_coefficient"  # (point, residual_term) complex
MAC = "mac"  # (mode, mode_2) modal assurance criterion
DRIVE_POINT_SNR = "drive_point_snr"  # (mode) drive-point peak contribution / noise floor
QUALITY_FLAGS = "quality_flags"  # (mode) int32 bit field of FLAG_MEANINGS (0 when none)
ATTR_AMI_MODEL = "ami_model"  # "discrete" | "continuous": basis used by the phases
ATTR_AMI_PHASE = "ami_phase"  # last AMI phase run: subtract | isolate | global_fit | identify
# the phases of identify, as a progress report names them
PHASE_SUBTRACT = "subtract"
PHASE_ISOLATE = "isolate"
PHASE_GLOBAL_FIT = "global_fit"
PHASE_REFINE = "refine"
# Settings of the phases, one attribute per setting (ami_xr.ami.settings writes and reads them)
ATTR_AMI_DELTA = "ami_delta"  # subtract: fit-band level as a fraction of the peak
ATTR_AMI_PFA = "ami_false_alarm_probability"  # subtract: false-alarm probability of the stop
ATTR_AMI_MAX_MODES = "ami_max_modes"  # subtract: most candidates per FRF
ATTR_AMI_MIN_POINTS = "ami_min_points"  # subtract: fewest lines of a fit band
ATTR_AMI_ZETA_MAX = "ami_zeta_max"  # subtract: largest physical damping ratio
ATTR_AMI_MERGE_TOL = "ami_merge_tol"  # subtract: duplicate distance, half-power bandwidths
ATTR_AMI_METHOD = "ami_method"  # isolate: METHOD_SIMO | METHOD_PER_FRF
ATTR_AMI_WEIGHTING = "ami_weighting"  # isolate: WEIGHTING_SNR | WEIGHTING_MEAN
METHOD_SIMO = "simo"  # global SIMO isolation (Allen & Ginsberg)
METHOD_PER_FRF = "per_frf"  # each FRF isolated on its own (the paper)
METHOD_PAPER = "paper"  # identify: the paper's AMI exactly (per_frf, mean, continuous, no refine)
WEIGHTING_SNR = "snr"  # per_frf averaging with weights snr^2
WEIGHTING_MEAN = "mean"  # plain mean (the paper)
ATTR_AMI_TOL = "ami_tol"  # isolate: relative convergence tolerance
ATTR_AMI_BAND = "ami_band"  # global_fit: band half-width in half-power bandwidths, or "all"
ATTR_AMI_BAND_USED = "ami_band_used"  # global_fit: the band it widened to (too few lines)
ATTR_AMI_RESIDUAL_TERMS = "ami_residual_terms"  # global_fit: 1 with residual terms, else 0
ATTR_AMI_DRIVE_SNR_MIN = "ami_drive_snr_min"  # global_fit: threshold of low_drive_point_snr
ATTR_AMI_STOP_REASON = "ami_stop_reason"  # subtract, when no FRF has a candidate: why (below)
STOP_NO_SIGNIFICANT_PEAK = "no_significant_peak"  # no FRF has a peak above its noise floor
STOP_NO_ACCEPTED_FIT = "no_accepted_fit"  # peaks above the noise floor, but no fit accepted
# The analysis band (ami_xr.dsp.band): identify analyses only these lines, reports no mode outside
ATTR_BAND_FMIN = "analysis_band_fmin"  # Hz, lowest line analysed
ATTR_BAND_FMAX = "analysis_band_fmax"  # Hz, highest line analysed
ATTR_BAND_RULE = "analysis_band_rule"  # "excitation" | "whole" | "user"
ATTR_BAND_USER_GIVEN = "analysis_band_user_given"  # "", "fmin", "fmax" or "fmin,fmax"
ATTR_BAND_REASON = "analysis_band_reason"  # one sentence: why this band
ATTR_BAND_FORCE_DROP_DB = "analysis_band_force_drop_db"  # force rule: dB below its low level
ATTR_BAND_COHERENCE_MIN = "analysis_band_coherence_min"  # coherence rule: level
ATTR_BAND_COHERENCE_FRACTION = "analysis_band_coherence_fraction"  # ... fraction of lines
ATTR_BAND_DROPPED = "analysis_band_dropped_modes"  # Hz of modes outside the band, dropped
# Caps that ended a phase: an int, the bits of ami_xr.core.flags.RunStatus (words in its CAPS)
ATTR_AMI_CAPPED = "ami_capped"
# caps that did not decide the result: subtraction caps when the refinement completed the model,
# isolate:max_iter when the converged refinement re-fitted every mode
ATTR_AMI_CAPPED_SUPERSEDED = "ami_capped_superseded"
MODE_LABEL_UNSORTED = "mode_label_unsorted"  # (mode) label before sorting by frequency
# Results of ami_xr.refine, as attributes
ATTR_REFINE_MODEL = "refine_model"  # "discrete" | "continuous"
ATTR_REFINE_RESIDUAL_TERMS = "refine_residual_terms"  # "", "lower", "upper" or "lower,upper"
ATTR_REFINE_ITERATIONS = "refine_iterations"
ATTR_REFINE_FULL_FITS = "refine_full_fits"  # fits on every line of the band (cost driver)
ATTR_REFINE_CONVERGED = "refine_converged"  # 1 | 0
ATTR_REFINE_COST_START = "refine_cost_start"  # objective sum_j (n/2) log |r_j|^2 at the start
ATTR_REFINE_COST = "refine_cost"  # ... and at the optimum
ATTR_REFINE_REMOVED_MODES = "refine_removed_modes"  # comma-separated labels of dropped modes
# split duplicates merged by the close-pair order test: "F_dropped Hz into F_kept Hz, ..."
ATTR_REFINE_MERGED_MODES = "refine_merged_modes"
# modes of close pairs the order test kept (the data support both): "F Hz, ..."
ATTR_REFINE_CLOSE_PAIRS_SUPPORTED = "refine_close_pairs_supported"
# Core dims of intermediate results (never in a returned Dataset)
SLOT = "slot"  # per-FRF mode slots of the per_frf isolation
FREQUENCY_OUT = "frequency_out"  # frequency as an output core dim (apply_ufunc needs a new name)
MODEL_DISCRETE = "discrete"  # exact basis of dt * DFT of a sampled impulse response
MODEL_CONTINUOUS = "continuous"  # eq. 4
AMI_MODELS = (MODEL_DISCRETE, MODEL_CONTINUOUS)  # values of ATTR_AMI_MODEL and refine_model
ATTR_EXP_CORRECTED = "exponential_window_corrected"  # 1/s added to Re(lambda), when done
ATTR_THRESHOLD = "threshold"  # on SUB_STOP_STATISTIC: the stop level t of the statistic
ATTR_SCALING = "scaling"  # on MODE_VECTOR: how the mode vectors are scaled
ATTR_CRB_MODEL = "crb_model"  # cramer_rao_bound: "discrete" | "continuous"
# Multi-reference identification (ami_xr.ami.mimo)
PARTICIPATION = "participation"  # (mode, reference) modal participation factor L, A = lam phi L^T
RANK_ONE_RATIO = "rank_one_ratio"  # (mode) s2/s1 of the residue matrix (point x reference)
DRIVE_POINT_CONSISTENCY = "drive_point_consistency"  # (mode) spread of drive-point scalings
SCALING_REFERENCE = "scaling_reference"  # (mode) the reference whose drive point scaled phi
FLAG_REPEATED_ROOT = "repeated_root_suspected"  # residue matrix of a mode not rank one
ATTR_RANK_ONE_RATIO_MAX = "rank_one_ratio_max"  # threshold of FLAG_REPEATED_ROOT on s2/s1
ATTR_MULTI_REFERENCE = "multi_reference"  # identify: how several references were combined
FLAG_REPEATED_ROOT_SEPARATED = "repeated_root_separated"  # one of two modes at one eigenvalue
# Logger of the once-per-process "compiling numeric kernels" notice (INFO; the CLI shows it)
COMPILE_LOGGER = "ami_xr.compile"
# Mode stability diagnostic (ami_xr.ami.stability): identify re-run over detection thresholds
# (pfa) and analysis bands, each reference mode matched to the modes of every variant
STABILITY_VARIANT = "stability_variant"  # dim: one identify variant, labelled "pfa=1e-3, ..."
STABILITY_PFA = "stability_pfa"  # (stability_variant) false-alarm probability of the variant
STABILITY_FMIN = "stability_band_fmin"  # (stability_variant) Hz, variant's analysis band
STABILITY_FMAX = "stability_band_fmax"  # (stability_variant) Hz
STABILITY_FOUND = "stability_found"  # (mode, stability_variant) bool: matched in that variant
STABILITY_IN_BAND = "stability_in_band"  # (mode, stability_variant) bool: inside its band
STABILITY_FREQUENCY = "stability_frequency"  # (mode, stability_variant) Hz of the match, NaN
STABILITY_FRACTION = "stability_fraction"  # (mode) found / in-band variants, 0..1
STABILITY_FREQUENCY_SPREAD = "stability_frequency_spread"  # (mode) Hz, std of matches
ATTR_STABILITY_RULE = "stability_rule"  # one sentence: variants, match radius, fraction
ATTR_STABILITY_TOLERANCE = "stability_match_tolerance"  # match radius in units of |Re lam|
# The quality flags of a mode as named bits, bit k = 2**k for FLAG_MEANINGS[k]: the one encoding
# of QUALITY_FLAGS (ami_xr.core.flags), in memory and on disk (where ami_xr.io.cf adds the CF
# flag_masks/flag_meanings); text (the flags set, in this order, joined by FLAG_SEPARATOR) only
# in tables and reports.
# Never reorder, only append (files hold the bits).
FLAG_MEANINGS = (
    FLAG_LOW_DRIVE_SNR,
    FLAG_UNSCALED,
    FLAG_NOT_CONVERGED,
    FLAG_SINGLE_FRF,
    FLAG_REFINE_NOT_CONVERGED,
    FLAG_REFINE_FALLBACK,
    FLAG_ADDED_BY_REFINE,
    FLAG_REPEATED_ROOT,
    FLAG_REPEATED_ROOT_SEPARATED,
    FLAG_UNDER_RESOLVED,
)
# Noise the simulator added (ami_xr.simulate.noise), read by the Cramer-Rao bound (ami_xr.ami.crb)
ATTR_NOISE_LEVEL = "noise_level"  # alpha of eq. 15
ATTR_NOISE_KIND = "noise_kind"  # "uniform" | "gaussian"
NOISE_KINDS = ("uniform", "gaussian")
