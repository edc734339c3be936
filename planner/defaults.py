"""The defaults a user meets on the command line, in one light module (no NumPy, no solver).

The stages import their defaults from here, and the commands build their parsers from
here without importing the stages, so ``--help`` answers at once.
"""

UNIT_TO_M = {"mm": 0.001, "cm": 0.01, "m": 1.0, "in": 0.0254, "ft": 0.3048}
"""Length units accepted in drawings, layout files and ``--units`` [m per unit]."""

SCHEMES = ("auto", "paper", "window", "unique")
"""ID schemes ``vlp-plan --scheme`` offers."""

RECEIVERS = ("three", "gravity", "auto")
"""Receiver modes ``vlp-plan --receiver`` offers (:mod:`planner.receivers.modes`, and ``auto``)."""

ACCELEROMETER_SIGMA_DEG = 1.0
"""Default standard deviation of the gravity direction a phone's accelerometer gives [deg]."""

LINE_CODE_NAMES = ("4b6b", "manchester")
"""Line codes of the frames (:data:`planner.modulation.frame.LINE_CODES` holds them)."""

LOCATE_METHODS = ("paper", "perspective")
"""Positioning methods (:data:`planner.positioning.locate.METHODS` holds them)."""

DRIVER_MAX_HZ = 20_000.0
"""Default fastest chip rate a luminaire driver switches cleanly [Hz] (``--driver-max-hz``)."""

FLICKER_HZ = 200.0
"""Lowest allowed repetition of a light's slowest on/off cycle [Hz] (IEEE 802.15.7's flicker guidance): a frame's
longest run, or a tone's square wave (docs/tones.md)."""

VIDEO_FPS = 30.0
"""Default video frame rate of the receiver [1/s] (``--video-fps``), for frames read over several video frames."""

MAX_VIDEO_FPS = 1000.0
"""Largest ``--video-fps`` taken (phones film at 24-240 fps)."""

MAX_VIDEO_FRAMES = 4
"""Most consecutive video frames a plan may ask the phone to read a frame over (``--max-video-frames``)."""

ERROR_POSES_PER_M2 = 4.0
"""Default density of the poses an error map samples [1/m2] (each is observed and located)."""

POSES_PER_M2 = 400.0
"""Default density of sampled poses over the working area [1/m^2]."""

CONGRUENCE_TOLERANCE_M = 0.05
"""Side lengths closer than this are indistinguishable to the receiver [m]."""

INSTALL_TOLERANCE_M = 0.03
"""Default distance by which an installed luminaire may lie from its drawn position [m]."""

NOISE_PX = 0.5
"""Default standard deviation of an edge point's position [px] (before rounding)."""

# The error budget's terms besides edge noise (planner.positioning.error_terms; docs/positioning.md#error-budget).
INSTALL_ERROR_M = 0.02
"""Default radius [m] of the horizontal disc an installed luminaire lies in, uniformly, around its drawn
position (assumed: a ceiling grid set out from the drawing; within the windows' INSTALL_TOLERANCE_M)."""

FOCAL_ERROR_PCT = 0.5
"""Default standard deviation of the calibrated focal length's relative error [%] (the bound vlp-calibrate
meets on rendered boards, issue 18)."""

PRINCIPAL_ERROR_PX = 5.0
"""Default standard deviation of the calibrated principal point's error per axis [px] (assumed, for a
4000 px image)."""

DISTORTION_RESIDUAL_PX = 0.3
"""Default RMS over the image [px] of the lens distortion calibration leaves uncorrected (the
reprojection-error bound of vlp-calibrate, issue 18)."""

PHONE_SPEED_M_S = 0.5
"""Default speed of the phone while an image is read out [m/s] (assumed: walking slowly while looking at it;
people walk at 1.2-1.4 m/s)."""

PHONE_TURN_DEG_S = 5.0
"""Default angular rate of the hand-held phone while an image is read out [deg/s] (assumed: held steady)."""

MAX_PHONE_SPEED_M_S = 10.0
"""Fastest phone speed accepted [m/s]: beyond a sprint, a unit error rather than a user."""

MAX_PHONE_TURN_DEG_S = 1000.0
"""Fastest phone turn accepted [deg/s]."""

MAX_RESIDUAL_PX = 5.0
"""Default largest RMS ellipse residual [px] of a pose that explains an image."""

TWIN_TOLERANCE_M = 0.10
"""A twin's fix within this distance of the true position [m] counts as located."""

PAPER_RADIUS_M = 0.1
"""LED radius of the paper's rig [m]: not given there; assumed, the size of a common 18 W round panel."""

PAPER_TILTS_DEG = (0, 20, 30, 40)
"""Tilts of the paper's Table 3 [deg]."""

PAPER_LAYOUTS = {32: "grid-32.yaml", 256: "grid-256.yaml", 512: "grid-512.yaml"}
"""The bundled layouts (in ``layouts/``) of the paper's three cases."""

CURVE_SIZES = (16, 32, 64, 128, 256, 512, 1024, 2048, 4096, 10000, 30000, 100000)
"""Default luminaire counts of the curve."""

PITCH_M = 0.5
"""Lattice pitch of the curve's sites [m] (as ``benchmarks/run.py``)."""

WINDOW_UP_TO = 4096
"""Largest curve site whose window scheme is computed by default (about 30 s at 4096, 9 min at 100,000)."""

PAPER_UP_TO = 30000
"""Largest curve site whose paper scheme is computed by default (about 15 s at 30,000, 100 s at 100,000)."""

SENSOR_EXPOSURE_S = 25e-6
"""Default row exposure of the twin's sensor [s]."""

SENSOR_BLUR_PX = 0.8
"""Default optics blur of the twin's sensor, Gaussian sigma [px]."""

SENSOR_READ_NOISE_DN = 2.0
"""Default read noise of the twin's sensor, sigma [DN of 255]."""

MAX_EXTENT_M = 10_000.0
"""Largest plan coordinate accepted [m]: a site 20 km across is an error (usually of units), not a building."""

MAX_HEIGHT_M = 100.0
"""Highest mounting or receiver height accepted [m]."""

MAX_RADIUS_M = 10.0
"""Largest LED radius accepted [m]."""

MAX_SEED = 2**32 - 1
"""Largest random seed a flag takes (numpy's seeds are 32-bit here)."""

MAX_LUMINAIRES = 100_000
"""Most luminaires one plan holds (a layout, or ``--leds``): the work of the stages grows with it."""

MAX_OBSERVED_LEDS = 2_000
"""Most LEDs one observation file may list: more than any photo shows whole."""

MAX_PLAN_POSES = 50_000_000
"""Most camera poses one run samples unless ``--max-poses`` says otherwise (about 20 GB, 6 min: planner/plan/budget.py)."""

MAX_IMAGE_VERSION = 1_000_000
"""Highest image version the planner writes or vlp-flash signs: a version near 2^32 would leave a
driver no newer version to move to (docs/flashing.md); a million re-plans leave room enough."""

MCU_CLOCK_HZ = 16e6
"""Default clock of the drivers' microcontroller [Hz] (``--mcu-clock-hz``; the reference driver's ATmega328P):
the timer reload in the header, and a multi-frame chip rate is one it plays exactly."""

MAX_MCU_CLOCK_HZ = 1e9
"""Fastest driver microcontroller clock accepted [Hz]: the header's constants are 32-bit (``UL`` on an AVR)."""

MIN_RADIUS_M = 1e-3
"""Smallest LED radius accepted [m]: a disc under a millimetre is an error of units, and images to nothing."""

MAX_FOCAL_PX = 1e6
"""Longest focal length accepted [px]: 1,000 times a 1,000-pixel half-width, far beyond any phone lens."""

MAX_IMAGE_PX = 20_000
"""Largest image side accepted [px] (a 200 Mpx phone sensor is 16,320 px wide)."""

MAX_POSES_PER_M2 = 20_000.0
"""Densest pose sample a flag may ask for [1/m2] (50 times the default; a 128 m2 site then samples 2.6 million)."""

MAX_TWIN_POSES = 100_000
"""Most poses one ``vlp-twin`` batch renders (300 by default; a pose takes tens of milliseconds per core)."""

MAX_BLUR_PX = 50.0
"""Widest optics blur ``vlp-twin --blur-px`` accepts, Gaussian sigma [px]: an LED image is smeared past reading
long before; a wider kernel only costs time."""

MAX_TRIALS = 10_000
"""Most trials per test point ``vlp-accuracy --trials`` runs (the paper's 10, times 1,000)."""

MAX_TIME_LIMIT_S = 86_400.0
"""Longest search budget ``--time-limit`` accepts [deterministic s]: a day."""

COVERAGE_GOAL = 0.9
"""Default share of sampled poses a site should decode at (``vlp-plan --coverage-goal``, planner.advice.advise)."""

USABLE_COVERAGE = 0.5
"""Below this share of decodable sampled poses a plan is reported NOT USABLE (and vlp-plan exits 3)."""
