//! Payload types. All plain data: numbers and fixed arrays, no pointers.

use bytemuck::Zeroable;
use iceoryx2::prelude::ZeroCopySend;

/// Most beams in a scan.
pub const MAX_BEAMS: usize = 2048;
/// Most lines in a line set.
pub const MAX_LINES: usize = 512;
/// Most corners in a corner set.
pub const MAX_CORNERS: usize = 512;
/// Most pose hypotheses in a pose message.
pub const MAX_HYPOTHESES: usize = 32;
/// Most walls in a published map.
pub const MAX_WALLS: usize = 16384;
/// Words of a published map's seen free space (one bit a cell: 524288 cells, 145 m square at
/// 0.2 m; a larger raster is published coarser).
pub const MAX_SEEN_WORDS: usize = 8192;
/// Bytes of an implementation name (UTF-8, NUL padded).
pub const NAME_LEN: usize = 32;

/// The stages that stamp a message on its way, in pipeline order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(usize)]
pub enum Stage {
    Acquire = 0,
    Segment = 1,
    Localize = 2,
}

/// Number of [`Stage`]s.
pub const STAGES: usize = 3;

/// When a stage took a message in hand and when it let the result go (monotonic ns, 0 if the
/// message did not pass the stage).
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend, Zeroable)]
#[repr(C)]
pub struct StageSpan {
    pub enter_ns: u64,
    pub leave_ns: u64,
}

/// The common header of every message derived from a scan.
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend, Zeroable)]
#[repr(C)]
pub struct Header {
    /// Sequence number of the scan this message derives from.
    pub seq: u64,
    /// Acquisition time of that scan, monotonic ns.
    pub stamp_ns: u64,
    /// Per-stage enter/leave times, indexed by [`Stage`].
    pub stages: [StageSpan; STAGES],
    /// Name of the implementation that produced this message (the last stage's).
    pub producer: [u8; NAME_LEN],
}

impl Header {
    pub fn new(seq: u64, stamp_ns: u64) -> Self {
        Header { seq, stamp_ns, stages: [StageSpan::default(); STAGES], producer: [0; NAME_LEN] }
    }

    pub fn set_producer(&mut self, name: &str) {
        self.producer = name_bytes(name);
    }

    pub fn producer(&self) -> &str {
        name_str(&self.producer)
    }

    pub fn span(&mut self, stage: Stage) -> &mut StageSpan {
        &mut self.stages[stage as usize]
    }
}

/// `name` as NUL-padded bytes (cut at a character boundary if too long).
pub fn name_bytes(name: &str) -> [u8; NAME_LEN] {
    let mut out = [0u8; NAME_LEN];
    let mut end = name.len().min(NAME_LEN);
    while !name.is_char_boundary(end) {
        end -= 1;
    }
    out[..end].copy_from_slice(&name.as_bytes()[..end]);
    out
}

/// The name in NUL-padded bytes (empty if not UTF-8).
pub fn name_str(bytes: &[u8; NAME_LEN]) -> &str {
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(NAME_LEN);
    std::str::from_utf8(&bytes[..end]).unwrap_or("")
}

/// A pose in the map frame: x, y (metres), theta (radians, REP 103).
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend, Zeroable)]
#[repr(C)]
pub struct PoseMsgXyt {
    pub x: f64,
    pub y: f64,
    pub theta: f64,
}

/// `gema2/scan`: one laser scan. Its layout is a C struct's (docs/design.md, "Payloads as C
/// structs"), for sources outside Rust.
#[derive(Clone, Copy, Debug, ZeroCopySend, Zeroable)]
#[repr(C)]
#[type_name("gema2::ScanMsg")]
pub struct ScanMsg {
    pub header: Header,
    pub angle_min: f64,
    pub angle_increment: f64,
    pub range_min: f64,
    pub range_max: f64,
    /// 1 when `truth` holds the true sensor pose (simulator, corrected log).
    pub has_truth: u32,
    /// Readings in `ranges` (at most [`MAX_BEAMS`]).
    pub count: u32,
    pub truth: PoseMsgXyt,
    pub ranges: [f32; MAX_BEAMS],
    /// 1 when `odometry` holds the robot's odometry pose at the scan (a log's, a bag's): any
    /// frame, only the motion between two scans is read (the sequential localizer).
    pub has_odometry: u32,
    pub _pad: u32,
    pub odometry: PoseMsgXyt,
}

/// One fitted line.
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend, Zeroable)]
#[repr(C)]
pub struct LineMsg {
    /// Visible extent, sensor frame, metres.
    pub start: [f64; 2],
    pub end: [f64; 2],
    /// Standard deviation of the line's direction, radians.
    pub direction_sigma: f64,
    /// |l|: samples in the line.
    pub samples: u32,
    pub _pad: u32,
}

/// `gema2/lines`: the filtered lines of a scan.
#[derive(Clone, Copy, Debug, ZeroCopySend, Zeroable)]
#[repr(C)]
pub struct LinesMsg {
    pub header: Header,
    /// Lines before filtering (the size of L).
    pub raw_count: u32,
    pub count: u32,
    pub lines: [LineMsg; MAX_LINES],
}

/// One side of a corner (see `segment::Arm`).
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend, Zeroable)]
#[repr(C)]
pub struct ArmMsg {
    pub direction: [f64; 2],
    pub gap: f64,
    pub length: f64,
    pub samples: f64,
    pub direction_sigma: f64,
    pub line: u32,
    pub _pad: u32,
}

/// One corner (see `segment::Corner`), sensor frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend, Zeroable)]
#[repr(C)]
pub struct CornerMsg {
    pub position: [f64; 2],
    pub inner_angle: f64,
    pub orientation: f64,
    pub quality: f64,
    pub arms: [ArmMsg; 2],
}

/// `gema2/corners`: a scan's corners, best first, with the scan they derive from (the cost
/// function needs its readings) and its filtered lines (the localizer's slide search lays them
/// along walls when no corner matches).
#[derive(Clone, Copy, Debug, ZeroCopySend, Zeroable)]
#[repr(C)]
pub struct CornersMsg {
    pub scan: ScanMsg,
    pub count: u32,
    pub line_count: u32,
    /// The segmenter's e(d) was the configured one times this, the scan's measured noise
    /// (`segment::Segmentation::noise_scale`); the localizer widens its own alike. Values
    /// below 1 (a zeroed message) mean 1.
    pub noise_scale: f64,
    pub corners: [CornerMsg; MAX_CORNERS],
    pub lines: [LineMsg; MAX_LINES],
}

/// One pose hypothesis.
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend, Zeroable)]
#[repr(C)]
pub struct HypothesisMsg {
    pub pose: PoseMsgXyt,
    /// Eq. 7 (one-sided), mean per beam.
    pub cost: f64,
    pub inliers: f64,
    pub through: f64,
    pub scan_corner: u32,
    pub map_corner: u32,
}

/// Localization outcome codes.
pub const STATUS_OK: u32 = 0;
pub const STATUS_AMBIGUOUS: u32 = 1;
pub const STATUS_FAILED: u32 = 2;

/// An outcome code as every report writes it (`ok`, `ambiguous`, `failed`, as the localizer's
/// own `Status::as_str`); `unknown` for a code no localizer sends.
pub fn status_name(code: u32) -> &'static str {
    match code {
        STATUS_OK => "ok",
        STATUS_AMBIGUOUS => "ambiguous",
        STATUS_FAILED => "failed",
        _ => "unknown",
    }
}

/// `gema2/pose`: ranked hypotheses of a scan. Its layout is a C struct's (docs/design.md,
/// "Payloads as C structs"), read outside Rust by that name: `examples/pose_listener.py`.
#[derive(Clone, Copy, Debug, ZeroCopySend, Zeroable)]
#[repr(C)]
#[type_name("gema2::PoseMsg")]
pub struct PoseMsg {
    pub header: Header,
    /// [`STATUS_OK`], [`STATUS_AMBIGUOUS`] or [`STATUS_FAILED`].
    pub status: u32,
    pub count: u32,
    /// Candidates produced by corner matching.
    pub candidates: u32,
    /// Version of the map localized against.
    pub map_version: u32,
    pub has_truth: u32,
    /// How many scans the answer rests on: 1 for one scan's, more for the sequential
    /// localizer's, 0 with none.
    pub scans: u32,
    pub truth: PoseMsgXyt,
    pub hypotheses: [HypothesisMsg; MAX_HYPOTHESES],
}

/// `gema2/map`: the wall map, published with history so late joiners get it.
#[derive(Clone, Copy, Debug, ZeroCopySend, Zeroable)]
#[repr(C)]
pub struct MapMsg {
    /// Increases every time the map server (re)loads the map.
    pub version: u32,
    pub count: u32,
    /// The map's accuracy, metres (see `map::WallMap::sigma`).
    pub sigma: f64,
    /// Where the map's survey saw free space (see `map::SeenFree`): `seen_cols` x
    /// `seen_rows` cells of `seen_cell` metres from `seen_origin`, row by row, one bit each in
    /// `seen_bits`. No cells: the map has none.
    pub seen_origin: [f64; 2],
    pub seen_cell: f64,
    pub seen_cols: u32,
    pub seen_rows: u32,
    pub seen_bits: [u64; MAX_SEEN_WORDS],
    /// Walls as x1, y1, x2, y2 (metres).
    pub walls: [[f64; 4]; MAX_WALLS],
}

/// Request to the map server: corners with inner angle within `tolerance` of `inner_angle`,
/// optionally within `radius` of (`x`, `y`).
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend, Zeroable)]
#[repr(C)]
pub struct CornerQuery {
    pub inner_angle: f64,
    pub tolerance: f64,
    pub has_region: u32,
    pub _pad: u32,
    pub x: f64,
    pub y: f64,
    pub radius: f64,
}

/// A map corner in a reply.
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend, Zeroable)]
#[repr(C)]
pub struct MapCornerMsg {
    pub position: [f64; 2],
    pub inner_angle: f64,
    pub orientation: f64,
}

/// The map server's answer: up to [`MAX_CORNERS`] corners (`total` says how many matched).
#[derive(Clone, Copy, Debug, ZeroCopySend, Zeroable)]
#[repr(C)]
pub struct CornerReply {
    pub map_version: u32,
    pub count: u32,
    pub total: u32,
    pub _pad: u32,
    pub corners: [MapCornerMsg; MAX_CORNERS],
}

/// [`ControlRequest::what`]: replace a stage.
pub const CONTROL_SWAP: u32 = 0;
/// [`ControlRequest::what`]: say what each stage runs and what it can be swapped to.
pub const CONTROL_LIST: u32 = 1;
/// Bytes of a program's path in a control request (UTF-8, NUL padded).
pub const PATH_LEN: usize = 512;
/// Bytes of a control request's arguments: each argument followed by a NUL.
pub const ARGS_LEN: usize = 2048;
/// Bytes of the supervisor's answer (UTF-8, NUL padded).
pub const REPLY_LEN: usize = 4096;

/// Request to the supervisor (`gema2 swap`): replace `stage` by another implementation,
/// another program, or the same with other arguments; or list the stages.
#[derive(Clone, Copy, Debug, ZeroCopySend, Zeroable)]
#[repr(C)]
pub struct ControlRequest {
    /// [`CONTROL_SWAP`] or [`CONTROL_LIST`].
    pub what: u32,
    /// 1: `args` replace the stage's arguments; 0: they follow them.
    pub replace_args: u32,
    pub stage: [u8; NAME_LEN],
    /// Empty: the stage's own.
    pub implementation: [u8; NAME_LEN],
    /// A replacement the pipeline file names for the stage (`[[stage.alternative]]`); empty:
    /// none.
    pub alternative: [u8; NAME_LEN],
    /// Empty: the stage's own program.
    pub binary: [u8; PATH_LEN],
    /// Arguments, each followed by a NUL.
    pub args: [u8; ARGS_LEN],
}

/// The supervisor's answer: `ok` 1 on success, and a message.
#[derive(Clone, Copy, Debug, ZeroCopySend, Zeroable)]
#[repr(C)]
pub struct ControlReply {
    pub ok: u32,
    pub message: [u8; REPLY_LEN],
}

/// Bytes of a supervisor event's text.
pub const EVENT_LEN: usize = 512;

/// `<prefix>/events`: what the supervisor did to the pipeline (a swap, its failure), for the
/// recording and anyone watching.
#[derive(Clone, Copy, Debug, ZeroCopySend, Zeroable)]
#[repr(C)]
pub struct EventMsg {
    /// When, monotonic ns.
    pub stamp_ns: u64,
    /// 1 when what was asked was done.
    pub ok: u32,
    pub _pad: u32,
    /// UTF-8, NUL padded.
    pub text: [u8; EVENT_LEN],
}

/// `text` as NUL-padded bytes of length `N`, or `None` when it does not fit (or holds a NUL).
pub fn padded<const N: usize>(text: &str) -> Option<[u8; N]> {
    let b = text.as_bytes();
    if b.len() > N || b.contains(&0) {
        return None;
    }
    let mut out = [0u8; N];
    out[..b.len()].copy_from_slice(b);
    Some(out)
}

/// `text` as NUL-padded bytes of length `N`, cut at a character boundary so that at least one
/// NUL ends it: a message that may be longer than its slot (a reply, an event).
pub fn cut_padded<const N: usize>(text: &str) -> [u8; N] {
    let mut out = [0u8; N];
    let mut n = text.len().min(N.saturating_sub(1));
    while !text.is_char_boundary(n) {
        n -= 1;
    }
    out[..n].copy_from_slice(&text.as_bytes()[..n]);
    out
}

/// The text in NUL-padded bytes, up to the first NUL (lossy UTF-8).
pub fn unpadded(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes.split(|&b| b == 0).next().unwrap_or(&[])).into_owned()
}

/// Arguments packed as [`ControlRequest::args`] holds them; `None` when they do not fit.
pub fn pack_args(args: &[String]) -> Option<[u8; ARGS_LEN]> {
    let mut out = [0u8; ARGS_LEN];
    let mut at = 0;
    for a in args {
        let b = a.as_bytes();
        if b.contains(&0) || at + b.len() + 1 > ARGS_LEN {
            return None;
        }
        out[at..at + b.len()].copy_from_slice(b);
        at += b.len() + 1;
    }
    Some(out)
}

/// The arguments of [`pack_args`]' bytes.
pub fn unpack_args(bytes: &[u8; ARGS_LEN]) -> Vec<String> {
    let end = bytes.iter().rposition(|&b| b != 0).map_or(0, |k| k + 1);
    if end == 0 {
        return Vec::new();
    }
    bytes[..end].split(|&b| b == 0).map(|a| String::from_utf8_lossy(a).into_owned()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_are_cut_safely() {
        assert_eq!(name_str(&name_bytes("line-visibility")), "line-visibility");
        let long = "é".repeat(40);
        let cut = name_bytes(&long);
        assert!(name_str(&cut).chars().all(|c| c == 'é'));
        assert_eq!(name_str(&cut).len(), 32);
    }

    /// The C layout docs/design.md gives for `gema2/pose`, which readers in other languages
    /// mirror (examples/pose_listener.py): a change here is a change of that contract.
    #[test]
    fn the_pose_and_scan_messages_have_their_documented_c_layouts() {
        use std::mem::{align_of, offset_of, size_of};
        assert_eq!((size_of::<Header>(), offset_of!(Header, stages), offset_of!(Header, producer)), (96, 16, 64));
        assert_eq!((size_of::<HypothesisMsg>(), offset_of!(HypothesisMsg, scan_corner)), (56, 48));
        assert_eq!(offset_of!(PoseMsg, status), 96);
        assert_eq!(offset_of!(PoseMsg, truth), 120);
        assert_eq!(offset_of!(PoseMsg, hypotheses), 144);
        assert_eq!((size_of::<PoseMsg>(), align_of::<PoseMsg>()), (1936, 8));
        // SAFETY: type_name only returns the name the derive was given.
        assert_eq!(unsafe { <PoseMsg as ZeroCopySend>::type_name() }, "gema2::PoseMsg");
        assert_eq!(offset_of!(ScanMsg, angle_min), 96);
        assert_eq!(offset_of!(ScanMsg, has_truth), 128);
        assert_eq!(offset_of!(ScanMsg, truth), 136);
        assert_eq!(offset_of!(ScanMsg, ranges), 160);
        assert_eq!((offset_of!(ScanMsg, has_odometry), offset_of!(ScanMsg, odometry)), (8352, 8360));
        assert_eq!((size_of::<ScanMsg>(), align_of::<ScanMsg>()), (8384, 8));
        assert_eq!(offset_of!(PoseMsg, scans), 116);
        // SAFETY: as above.
        assert_eq!(unsafe { <ScanMsg as ZeroCopySend>::type_name() }, "gema2::ScanMsg");
    }

    #[test]
    fn arguments_pack_and_unpack_whole_or_not_at_all() {
        let args: Vec<String> = ["--set", "track=5", "", "--x"].iter().map(|s| s.to_string()).collect();
        let packed = pack_args(&args).unwrap();
        // an empty argument in the middle survives; a trailing one would read as padding
        assert_eq!(unpack_args(&packed), args);
        assert_eq!(unpack_args(&pack_args(&[]).unwrap()), Vec::<String>::new());
        assert!(pack_args(&["x".repeat(ARGS_LEN)]).is_none());
        assert!(pack_args(&["a\0b".into()]).is_none());
        assert_eq!(unpadded(&padded::<8>("abc").unwrap()), "abc");
        // cut at a character boundary, a NUL always left at the end
        assert_eq!(unpadded(&cut_padded::<6>("ab\u{e9}\u{e9}")), "ab\u{e9}");
        assert_eq!(cut_padded::<4>("abcdef"), *b"abc\0");
        assert!(padded::<2>("abc").is_none());
    }

    #[test]
    fn payloads_fit_shared_memory_comfortably() {
        assert!(std::mem::size_of::<ScanMsg>() < 16 * 1024);
        assert!(std::mem::size_of::<CornersMsg>() < 128 * 1024);
        assert!(std::mem::size_of::<MapMsg>() <= 600 * 1024);
    }
}
