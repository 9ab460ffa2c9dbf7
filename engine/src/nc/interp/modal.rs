//! Modal state: planes, motion modes, the G/M modal groups, and the `Modal` state that
//! M70/M72/M73 save and restore.

use super::{Interp, MM_PER_INCH};
use crate::nc::{FeedMode, SpindleDir};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Plane {
    XY,
    XZ,
    YZ,
}

impl Plane {
    /// First and second axis of the plane, then the normal axis (right-handed).
    pub(super) fn axes(self) -> [usize; 3] {
        match self {
            Plane::XY => [0, 1, 2],
            Plane::XZ => [2, 0, 1],
            Plane::YZ => [1, 2, 0],
        }
    }
    pub(super) fn normal(self) -> [f64; 3] {
        match self {
            Plane::XY => [0.0, 0.0, 1.0],
            Plane::XZ => [0.0, 1.0, 0.0],
            Plane::YZ => [1.0, 0.0, 0.0],
        }
    }
    /// Arc centre offset letters for the first and second axis.
    pub(super) fn ijk(self) -> [char; 2] {
        match self {
            Plane::XY => ['I', 'J'],
            Plane::XZ => ['K', 'I'],
            Plane::YZ => ['J', 'K'],
        }
    }
    /// The offset letter not allowed in this plane.
    pub(super) fn forbidden_ijk(self) -> char {
        match self {
            Plane::XY => 'K',
            Plane::XZ => 'J',
            Plane::YZ => 'I',
        }
    }
    pub(super) fn name(self) -> &'static str {
        match self {
            Plane::XY => "G17",
            Plane::XZ => "G18",
            Plane::YZ => "G19",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Motion {
    Rapid,
    Linear,
    Arc {
        cw: bool,
    },
    RigidTap,
    /// G38.2..G38.5 (the G number times ten)
    Probe(u16),
    /// G73, G81..G89 (the G number)
    Cycle(u16),
    /// G5 (cubic) / G5.1 (quadratic)
    Spline {
        cubic: bool,
    },
    /// G5.2: NURBS control points until G5.3
    Nurbs,
}

/// The motion modes (group 1) the interpreter keeps.
pub(super) struct MotionModes {
    /// The motion mode in force.
    pub(super) mode: Option<Motion>,
    /// Motion mode before the current block (decides whether a cycle's words are sticky).
    pub(super) prev: Option<Motion>,
    /// The last G0/G1/G2/G3 mode: a Fanuc G80 returns to it.
    pub(super) mode_01: Option<Motion>,
}

/// Modal group of a G code (times ten), LinuxCNC numbering; None: unsupported.
pub(super) fn g_group(code: u16) -> Option<u8> {
    Some(match code {
        40 | 100 | 280 | 281 | 282 | 300 | 301 | 310 | 520 | 530 | 531 | 920 | 921 | 922 | 923 => 0,
        0 | 10 | 20 | 30 | 50 | 51 | 52 | 53 | 331 | 382 | 383 | 384 | 385 | 730 | 740 | 800
        | 760 | 810 | 820 | 830 | 840 | 850 | 860 | 870 | 880 | 890 => 1,
        170 | 180 | 190 => 2,
        900 | 910 => 3,
        901 | 911 => 4,
        930 | 940 | 950 => 5,
        200 | 210 => 6,
        400 | 410 | 420 | 411 | 421 => 7,
        430 | 431 | 434 | 435 | 490 => 8,
        980 | 990 => 10,
        540 | 550 | 560 | 570 | 580 | 590 | 591 | 592 | 593 | 541 | 1540 => 12,
        610 | 611 | 640 => 13,
        960 | 970 => 14,
        // Fanuc's own groups: scaling, rotation, polar coordinates, mirror image.
        500 | 510 => 11,
        // G68.2 (tilted working plane) shares G68's group: G69 ends either.
        680 | 682 | 690 => 16,
        150 | 160 => 17,
        501 | 511 => 22,
        670 => 23,
        _ => return None,
    })
}

pub(super) fn g_name(code: u16) -> String {
    if code % 10 == 0 {
        format!("G{}", code / 10)
    } else {
        format!("G{}.{}", code / 10, code % 10)
    }
}

/// Why a G code is refused, for the error message.
pub(super) fn g_refusal(code: u16) -> &'static str {
    match code {
        70 | 80 => "lathe diameter/radius mode is not supported",
        // One number, several meanings: name each, so the message fits the program's.
        700 => "(LinuxCNC's lathe finishing cycle; a bolt-hole circle on Haas and Yasnac mills; inch units on Siemens, Heidenhain ISO and Fagor controls) is not supported: program bolt holes as the positions of a canned cycle, and units with G20/G21",
        710 | 711 | 712 => "(LinuxCNC's lathe roughing cycle; a bolt-hole arc on Haas and Yasnac mills; millimetre units on Siemens, Heidenhain ISO and Fagor controls) is not supported: program bolt holes as the positions of a canned cycle, and units with G20/G21",
        720 | 721 | 722 => "(LinuxCNC's lathe facing cycle; bolt holes along a line on Haas and Yasnac mills) is not supported: program the holes as the positions of a canned cycle",
        330 => "spindle-synchronized motion (G33) is not supported",
        380..=389 => "probing (G38.x) cannot be simulated without a probe model",
        310 => "(Fanuc's skip function, a probing move) is Fanuc's: with dialect fanuc (or auto on a Fanuc program); LinuxCNC probes with G38.2",
        760 => "(LinuxCNC's lathe threading cycle) is not supported; with dialect fanuc G76 is the fine boring cycle",
        650 => "macro call (G65) is Fanuc custom macro B: with dialect fanuc (or auto on a Fanuc program), written first in its block",
        660 => "modal macro call (G66) is Fanuc custom macro B: with dialect fanuc (or auto on a Fanuc program), written first in its block",
        661 => "modal macro call G66.1 (every block) is not supported",
        120 | 130 => "(Haas circular pocket milling) is not supported",
        121 | 131 => "(Fanuc polar coordinate interpolation, on mill-turn machines) is not supported",
        71 => "(Fanuc cylindrical interpolation) is not supported",
        470 => "(Haas text engraving) is not supported",
        1000 | 1010 => "(Haas programmable mirror image off/on) is not supported: Fanuc's G50.1/G51.1 are (with dialect fanuc, or auto on a Fanuc program)",
        1500 => "(Haas general-purpose pocket milling) is not supported",
        1410 => "(Haas 3-D cutter compensation) is not supported",
        2540 | 2550 => "(Haas dynamic work offset) is not supported: program the tool tip with G234 (or G43.4), or a 3+2 setup with G68.2 and G53.1",
        683 | 684 => "(tilted working plane from the tool axis, or incremental) is not supported: define the plane with G68.2 X Y Z I J K (origin and Euler angles), then G53.1 turns the tool normal to it",
        _ => "is not a supported G code",
    }
}

/// M code modal group (LinuxCNC numbering); None: not a known M code.
pub(super) fn m_group(code: u32) -> Option<u8> {
    Some(match code {
        0 | 1 | 2 | 30 | 60 | 97 | 98 | 99 => 4,
        6 | 61 => 6,
        // M19 orients the spindle: it stops it at an angle (LinuxCNC and Fanuc alike).
        3 | 4 | 5 | 19 => 7,
        7 | 8 | 9 => 8,
        48 | 49 | 50 | 51 | 52 | 53 => 9,
        70 | 71 | 72 | 73 => 5,
        _ => return None,
    })
}

/// Modal state saved by M70/M73 and restored by M72 (LinuxCNC).
#[derive(Clone, Debug)]
pub(super) struct Modal {
    pub(super) metric: bool,
    pub(super) absolute: bool,
    pub(super) arc_absolute: bool,
    pub(super) feed_mode: FeedMode,
    pub(super) plane: Plane,
    pub(super) retract_r_plane: bool,
    pub(super) cs: usize,
    pub(super) feed_word: f64,
    pub(super) feed_factor: f64,
    pub(super) speed: f64,
    pub(super) spindle: SpindleDir,
}

impl Interp<'_> {
    /// Back to a saved modal state (M72, or the return of an M73 subroutine): units convert
    /// the current position, a coordinate system change keeps the tool where it is.
    pub(super) fn restore_modal(&mut self, m: &Modal) {
        if self.modal.metric != m.metric {
            let f = if m.metric {
                MM_PER_INCH
            } else {
                1.0 / MM_PER_INCH
            };
            for i in 0..3 {
                self.cur[i] *= f;
            }
            self.modal.metric = m.metric;
        }
        if self.modal.cs != m.cs {
            self.change_offsets(|s| s.modal.cs = m.cs);
        }
        self.modal = m.clone();
    }
}
