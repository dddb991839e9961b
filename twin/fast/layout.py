"""Column names of the fast engine's state arrays (plain integer constants).

Robot parameters ``fp``/``ip`` and robot state ``fs``/``ist`` have one row per robot;
``gp``/``gi`` are line parameters, ``gs``/``gf`` the line's state (event counter, gateway
epochs, stream positions, the clock).
"""

from pnp_twin.twin.plan import RULES, SCHEMES

# robot float parameters fp[r, .]
BA, BB, XLO, QUAD, VR, ACC, PICK, PLACE, BX, BY, BASEX, BASEY, MTBF, MTTR = range(14)
REACH, MOUNTX, MOUNTY, BINSIDE = range(14, 18)  # reach (0: none) from the mount; SD's sign
N_FP = 18
# robot int parameters ip[r, .]
RULE, FAILMODE = range(2)
PRIO = 2  # rank among facing robots on an exact tie (lower first)
FILTER = 3  # bits: TESTS (kinds or reach to test, Robot.filtered), RIVALS (facing robots)
TESTS, RIVALS = 1, 2
N_IP = 4
NOFAIL, EXPONENTIAL, FIXED = range(3)
# per robot and kind parameters kp[r, kind, .]
KPICKS, KPICK, KPLACE, KVALUE = range(4)  # picks this kind (1/0), grip, release, value
N_KP = 4
# rule codes (twin.plan.RULES' indices), then the NooP column of the decision counts
FIFO, LIFO, SIRO, SD, LD, SPT, VAL, NOOP = range(8)
RULE_NAMES = (*RULES, "NooP")
assert RULE_NAMES == ("FIFO", "LIFO", "SIRO", "SD", "LD", "SPT", "VAL", "NooP")
EXTERNAL = 8  # ip[r, RULE]: the caller chooses (the kernel stops with ST_CHOOSE)
NO_RULE = -1  # the rule code of a pick whose policy names no rule ("?")
# line float parameters gp[.]
V, TICK, END_AT, CHANGE, HALF, TWO = range(6)
N_GP = 6
# line int parameters gi[.]
SCHEME, CAPACITY, HOLD = range(3)  # HOLD: pause at every decision epoch (environments)
N_GI = 3
# the outfeed og[.] (float, line): on (1.0) or not, signed speed, mean s between containers,
# where a container's centre enters, the outfeed's centre line, slots, where the per-robot
# block and the containers' entry times start in og, and how many containers; then each
# slot's dx, dy, then the blocks. One array: every array in Params is passed on each call of
# a compiled function, so the outfeed adds one, not three.
OUT_ON, OUT_U, OUT_GAP, OUT_XIN, OUT_Y, OUT_NS, OUT_ORB, OUT_TIMES, OUT_NT = range(9)
N_OG = 9  # slot k's dx at N_OG + 2 k, its dy at N_OG + 2 k + 1
# per robot and slot, og[og[OUT_ORB] + (r * slots + k) * N_ORB + .]: the robot's place
# interval at the slot's y, and the s after a container enters until the slot enters that
# interval (inf: never)
OLO, OHI, OENTRY = range(3)
N_ORB = 3
T_CONTINUE, T_ALL, T_ANY = range(3)  # twin.plan.SCHEMES' indices
SCHEME_CODES = {name: code for code, name in enumerate(SCHEMES)}
assert SCHEME_CODES == {"t_continue": T_CONTINUE, "t_all": T_ALL, "t_any": T_ANY}
# robot float state fs[r, .]
TOOLX, TOOLY, NEXTFAIL, APPROACH, T0, TAPP, TX, TY, WAKE, WAIT0, BINREADY, DOWN0 = range(12)
CAL, CALW = 12, 14  # CAL + j, CALW + j: an event calendar node's robot and its wake-up
HOLD0, SLOTX, SLOTY = 16, 17, 18  # a hold's start (-inf: none); the tool after a place
N_FS = 19  # then one BINREADY column per kind code above 0 (N_FS + kind - 1)
# robot int state ist[r, .]
PC, ACTIVE, WPRIO, WSEQ, CLAIMED, PART, DOWN, WAITING, EXPECTED = range(9)
BINCOUNT, BOXES, EXPIDX = range(9, 12)
HINT_LO, HINT_HI = range(12, 14)  # last answers of the robot's belt bisections
MASK = 14  # scratch: the robots of a decision epoch being opened
RULENOW = 15  # rule code of the robot's current claim (recorded with its pick)
PENDING = 16  # hold mode: the robot is in the epoch the caller must answer
LASTCLAIM = 17  # the part of the robot's last claim (environments reset it to -1)
NOOPPART = 18  # the part whose entry timed the robot's last NooP (n parts: none)
NOOPSTAMP = 19  # gs[RELEASES] when NOOPPART was found (it bounds the next search if equal)
N_IS = 20  # then one BINCOUNT column per kind code above 0 (N_IS + kind - 1)
# line int state gs[.]
SEQ, EPOCHS, SIROIDX, NSPANS, STATUS = range(5)
DROBOT, DN, NPENDING = range(5, 8)  # ST_CHOOSE: the robot, its candidates; hold: epoch size
ROOMFOR = 8  # ST_ROOM: ROOM_SPANS, ROOM_SIRO or ROOM_EXPS (and the robot in DROBOT)
RELEASES = 9  # claims released (t_any) or parts replaced (rollouts): NOOPSTAMPs go stale
N_GS = 10
NOW = 0  # gf[NOW]
# program counters: where a robot resumes when its wake-up is processed
PC_START, PC_NOOP, PC_HELD, PC_APPROACH, PC_PLACE, PC_INTERRUPT, PC_DOWN = range(7)
PC_HOLDING = 7  # holding a gripped part until an outfeed slot comes into reach
# SimPy event priorities
URGENT, NORMAL = 0, 1
# span states
S_WAIT, S_INTERRUPTED, S_NOOP, S_BLOCKED, S_DOWN, S_HOLDING = range(6)
SPAN_NAMES = ("wait", "interrupted", "noop", "blocked", "down", "holding")
# run status
ST_OK, ST_SPANS, ST_SIRO, ST_EXPS = range(4)
ST_CHOOSE = 4  # a robot with rule EXTERNAL has candidates: call choose_external
ST_EPOCH = 5  # hold mode: a decision epoch is pending: call release
ST_ROOM = 6  # before an event: a buffer or pre-drawn stream is nearly full; grow it, go on
ROOM_SPANS, ROOM_SIRO, ROOM_EXPS = range(3)  # gs[ROOMFOR] with ST_ROOM: which one
SPAN_MARGIN, SIRO_MARGIN, EXP_MARGIN = 4, 4, 2  # room kept free (an event needs less)
