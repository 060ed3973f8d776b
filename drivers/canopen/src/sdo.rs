//! SDO: the service data protocol (client 0x600 + node, server 0x580 + node), expedited and
//! segmented transfers, abort codes, the client-side transfer state machines ([`Download`],
//! [`Upload`]) and the server side ([`Server`], over any object dictionary that implements
//! [`Dictionary`]). Block transfers are recognised and refused, as a server without them
//! must.

use crate::frame::{CanFrame, CobId, FrameError, Function, NodeId};

/// An SDO abort code (CiA 301, table 22), named where the standard names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct AbortCode(pub u32);

impl AbortCode {
    /// Toggle bit not alternated.
    pub const TOGGLE: AbortCode = AbortCode(0x0503_0000);
    /// SDO protocol timed out.
    pub const TIMEOUT: AbortCode = AbortCode(0x0504_0000);
    /// Command specifier not valid or unknown.
    pub const BAD_COMMAND: AbortCode = AbortCode(0x0504_0001);
    /// Out of memory (an object larger than the other side takes).
    pub const OUT_OF_MEMORY: AbortCode = AbortCode(0x0504_0005);
    /// Object does not exist in the object dictionary.
    pub const NO_OBJECT: AbortCode = AbortCode(0x0602_0000);
    /// Sub-index does not exist.
    pub const NO_SUBINDEX: AbortCode = AbortCode(0x0609_0011);
    /// Attempt to write a read-only object.
    pub const READ_ONLY: AbortCode = AbortCode(0x0601_0002);
    /// Attempt to read a write-only object.
    pub const WRITE_ONLY: AbortCode = AbortCode(0x0601_0001);
    /// Data type or length does not match.
    pub const LENGTH_MISMATCH: AbortCode = AbortCode(0x0607_0010);
    /// Object cannot be mapped to the PDO.
    pub const NOT_MAPPABLE: AbortCode = AbortCode(0x0604_0041);
    /// The mapped objects would exceed the PDO length.
    pub const PDO_TOO_LONG: AbortCode = AbortCode(0x0604_0042);
    /// Invalid value for parameter (download only).
    pub const INVALID_VALUE: AbortCode = AbortCode(0x0609_0030);
    /// Value of parameter written too high.
    pub const VALUE_TOO_HIGH: AbortCode = AbortCode(0x0609_0031);
    /// Data cannot be transferred because of the present device state.
    pub const DEVICE_STATE: AbortCode = AbortCode(0x0800_0022);
    /// General error.
    pub const GENERAL: AbortCode = AbortCode(0x0800_0000);

    /// The standard's description of the code.
    pub fn describe(self) -> &'static str {
        match self.0 {
            0x0503_0000 => "toggle bit not alternated",
            0x0504_0000 => "SDO protocol timed out",
            0x0504_0001 => "client/server command specifier not valid or unknown",
            0x0504_0002 => "invalid block size",
            0x0504_0003 => "invalid sequence number",
            0x0504_0004 => "CRC error",
            0x0504_0005 => "out of memory",
            0x0601_0000 => "unsupported access to an object",
            0x0601_0001 => "attempt to read a write-only object",
            0x0601_0002 => "attempt to write a read-only object",
            0x0602_0000 => "object does not exist in the object dictionary",
            0x0604_0041 => "object cannot be mapped to the PDO",
            0x0604_0042 => "mapped objects would exceed the PDO length",
            0x0604_0043 => "general parameter incompatibility",
            0x0604_0047 => "general internal incompatibility in the device",
            0x0606_0000 => "access failed due to a hardware error",
            0x0607_0010 => "data type does not match, length of service parameter does not match",
            0x0607_0012 => "data type does not match, length of service parameter too high",
            0x0607_0013 => "data type does not match, length of service parameter too low",
            0x0609_0011 => "sub-index does not exist",
            0x0609_0030 => "invalid value for parameter",
            0x0609_0031 => "value of parameter written too high",
            0x0609_0032 => "value of parameter written too low",
            0x0609_0036 => "maximum value is less than minimum value",
            0x060a_0023 => "resource not available: SDO connection",
            0x0800_0000 => "general error",
            0x0800_0020 => "data cannot be transferred or stored to the application",
            0x0800_0021 => "data cannot be transferred because of local control",
            0x0800_0022 => "data cannot be transferred because of the present device state",
            0x0800_0023 => "object dictionary dynamic generation failed or no object dictionary",
            0x0800_0024 => "no data available",
            _ => "unknown abort code",
        }
    }
}

impl std::fmt::Display for AbortCode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:#010x} ({})", self.0, self.describe())
    }
}

/// What the first message of a transfer carries.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Initiate {
    /// 1 to 4 data bytes in the message itself.
    Expedited(Vec<u8>),
    /// Segments follow; the total size when indicated.
    Segmented(Option<u32>),
}

/// A message from the SDO client (the host) to the server (the drive).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ClientRequest {
    /// Start writing `index`/`sub`.
    InitiateDownload {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Data or size.
        data: Initiate,
    },
    /// One segment of a write (at most 7 bytes).
    DownloadSegment {
        /// Toggle bit.
        toggle: bool,
        /// Data.
        data: Vec<u8>,
        /// True for the last segment.
        last: bool,
    },
    /// Start reading `index`/`sub`.
    InitiateUpload {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
    /// Ask for the next segment of a read.
    UploadSegment {
        /// Toggle bit.
        toggle: bool,
    },
    /// A block transfer (command specifier 5, upload, or 6, download); `index`/`sub` are
    /// those of an initiate request.
    Block {
        /// True for a block download, false for a block upload.
        download: bool,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
    /// Abort the transfer.
    Abort {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Why.
        code: AbortCode,
    },
}

/// A message from the SDO server (the drive) to the client.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ServerResponse {
    /// The write may proceed (or, expedited, is done).
    DownloadInitiated {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
    /// A write segment was received.
    DownloadSegmentAck {
        /// Toggle bit.
        toggle: bool,
    },
    /// The read starts: expedited data, or segments to follow.
    UploadInitiated {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Data or size.
        data: Initiate,
    },
    /// One segment of a read.
    UploadSegment {
        /// Toggle bit.
        toggle: bool,
        /// Data (at most 7 bytes).
        data: Vec<u8>,
        /// True for the last segment.
        last: bool,
    },
    /// The server aborted the transfer.
    Abort {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Why.
        code: AbortCode,
    },
}

fn mux(index: u16, sub: u8) -> [u8; 3] {
    let [a, b] = index.to_le_bytes();
    [a, b, sub]
}

fn initiate_bytes(base: u8, index: u16, sub: u8, data: &Initiate) -> Result<[u8; 8], FrameError> {
    let mut d = [0u8; 8];
    d[1..4].copy_from_slice(&mux(index, sub));
    match data {
        Initiate::Expedited(bytes) => {
            if bytes.is_empty() || bytes.len() > 4 {
                return Err(FrameError::Unexpected(
                    "expedited data must be 1 to 4 bytes",
                ));
            }
            d[0] = base | ((4 - bytes.len() as u8) << 2) | 0b11;
            d[4..4 + bytes.len()].copy_from_slice(bytes);
        }
        Initiate::Segmented(Some(size)) => {
            d[0] = base | 0b01;
            d[4..].copy_from_slice(&size.to_le_bytes());
        }
        Initiate::Segmented(None) => d[0] = base,
    }
    Ok(d)
}

fn parse_initiate(d: &[u8]) -> Initiate {
    let e = d[0] & 0b10 != 0;
    let s = d[0] & 0b01 != 0;
    if e {
        let n = if s {
            4 - ((d[0] >> 2) & 0b11) as usize
        } else {
            4
        };
        Initiate::Expedited(d[4..4 + n].to_vec())
    } else if s {
        Initiate::Segmented(Some(u32::from_le_bytes([d[4], d[5], d[6], d[7]])))
    } else {
        Initiate::Segmented(None)
    }
}

fn segment_bytes(base: u8, toggle: bool, data: &[u8], last: bool) -> Result<[u8; 8], FrameError> {
    if data.len() > 7 {
        return Err(stride_can::FrameError::TooLong(data.len()).into());
    }
    let mut d = [0u8; 8];
    d[0] = base | ((toggle as u8) << 4) | (((7 - data.len()) as u8) << 1) | last as u8;
    d[1..1 + data.len()].copy_from_slice(data);
    Ok(d)
}

fn parse_segment(d: &[u8]) -> (bool, Vec<u8>, bool) {
    let n = 7 - ((d[0] >> 1) & 0b111) as usize;
    (d[0] & 0x10 != 0, d[1..1 + n].to_vec(), d[0] & 1 != 0)
}

fn abort_bytes(index: u16, sub: u8, code: AbortCode) -> [u8; 8] {
    let mut d = [0x80, 0, 0, 0, 0, 0, 0, 0];
    d[1..4].copy_from_slice(&mux(index, sub));
    d[4..].copy_from_slice(&code.0.to_le_bytes());
    d
}

fn index_sub(d: &[u8]) -> (u16, u8) {
    (u16::from_le_bytes([d[1], d[2]]), d[3])
}

fn node_of(frame: &CanFrame, function: Function) -> Result<NodeId, FrameError> {
    CobId::parse(frame.raw_id() as u16)
        .filter(|c| c.function == function && !frame.is_extended())
        .and_then(|c| c.node)
        .ok_or(FrameError::Unexpected("not an SDO frame of that direction"))
}

impl ClientRequest {
    /// The frame to node `node` (COB-ID 0x600 + node).
    pub fn encode(&self, node: NodeId) -> Result<CanFrame, FrameError> {
        let d = match self {
            ClientRequest::InitiateDownload { index, sub, data } => {
                initiate_bytes(0x20, *index, *sub, data)?
            }
            ClientRequest::DownloadSegment { toggle, data, last } => {
                segment_bytes(0x00, *toggle, data, *last)?
            }
            ClientRequest::InitiateUpload { index, sub } => {
                let mut d = [0x40, 0, 0, 0, 0, 0, 0, 0];
                d[1..4].copy_from_slice(&mux(*index, *sub));
                d
            }
            ClientRequest::UploadSegment { toggle } => {
                [0x60 | ((*toggle as u8) << 4), 0, 0, 0, 0, 0, 0, 0]
            }
            ClientRequest::Block {
                download,
                index,
                sub,
            } => {
                // The initiate request; a block upload asks for blocks of 127 segments.
                let mut d = [if *download { 0xc0 } else { 0xa0 }, 0, 0, 0, 0, 0, 0, 0];
                d[1..4].copy_from_slice(&mux(*index, *sub));
                if !*download {
                    d[4] = 127;
                }
                d
            }
            ClientRequest::Abort { index, sub, code } => abort_bytes(*index, *sub, *code),
        };
        Ok(CanFrame::standard(
            CobId::of(Function::SdoRx, node).raw(),
            &d,
        )?)
    }

    /// Reads a client frame (as a server does): the addressed node and the request.
    pub fn decode(frame: &CanFrame) -> Result<(NodeId, ClientRequest), FrameError> {
        let node = node_of(frame, Function::SdoRx)?;
        let d = frame.data_at_least(8)?;
        let req = match d[0] >> 5 {
            1 => {
                let (index, sub) = index_sub(d);
                ClientRequest::InitiateDownload {
                    index,
                    sub,
                    data: parse_initiate(d),
                }
            }
            0 => {
                let (toggle, data, last) = parse_segment(d);
                ClientRequest::DownloadSegment { toggle, data, last }
            }
            2 => {
                let (index, sub) = index_sub(d);
                ClientRequest::InitiateUpload { index, sub }
            }
            3 => ClientRequest::UploadSegment {
                toggle: d[0] & 0x10 != 0,
            },
            5 | 6 => {
                let (index, sub) = index_sub(d);
                ClientRequest::Block {
                    download: d[0] >> 5 == 6,
                    index,
                    sub,
                }
            }
            4 => {
                let (index, sub) = index_sub(d);
                ClientRequest::Abort {
                    index,
                    sub,
                    code: AbortCode(u32::from_le_bytes([d[4], d[5], d[6], d[7]])),
                }
            }
            _ => return Err(FrameError::Unexpected("unknown SDO client command")),
        };
        Ok((node, req))
    }
}

impl ServerResponse {
    /// The frame from node `node` (COB-ID 0x580 + node).
    pub fn encode(&self, node: NodeId) -> Result<CanFrame, FrameError> {
        let d = match self {
            ServerResponse::DownloadInitiated { index, sub } => {
                let mut d = [0x60, 0, 0, 0, 0, 0, 0, 0];
                d[1..4].copy_from_slice(&mux(*index, *sub));
                d
            }
            ServerResponse::DownloadSegmentAck { toggle } => {
                [0x20 | ((*toggle as u8) << 4), 0, 0, 0, 0, 0, 0, 0]
            }
            ServerResponse::UploadInitiated { index, sub, data } => {
                initiate_bytes(0x40, *index, *sub, data)?
            }
            ServerResponse::UploadSegment { toggle, data, last } => {
                segment_bytes(0x00, *toggle, data, *last)?
            }
            ServerResponse::Abort { index, sub, code } => abort_bytes(*index, *sub, *code),
        };
        Ok(CanFrame::standard(
            CobId::of(Function::SdoTx, node).raw(),
            &d,
        )?)
    }

    /// Reads a server frame (as a client does): the answering node and the response.
    pub fn decode(frame: &CanFrame) -> Result<(NodeId, ServerResponse), FrameError> {
        let node = node_of(frame, Function::SdoTx)?;
        let d = frame.data_at_least(8)?;
        let resp = match d[0] >> 5 {
            3 => {
                let (index, sub) = index_sub(d);
                ServerResponse::DownloadInitiated { index, sub }
            }
            1 => ServerResponse::DownloadSegmentAck {
                toggle: d[0] & 0x10 != 0,
            },
            2 => {
                let (index, sub) = index_sub(d);
                ServerResponse::UploadInitiated {
                    index,
                    sub,
                    data: parse_initiate(d),
                }
            }
            0 => {
                let (toggle, data, last) = parse_segment(d);
                ServerResponse::UploadSegment { toggle, data, last }
            }
            4 => {
                let (index, sub) = index_sub(d);
                ServerResponse::Abort {
                    index,
                    sub,
                    code: AbortCode(u32::from_le_bytes([d[4], d[5], d[6], d[7]])),
                }
            }
            _ => return Err(FrameError::Unexpected("unknown SDO server command")),
        };
        Ok((node, resp))
    }
}

/// Why a transfer ended without success.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SdoError {
    /// The server aborted.
    #[error("node aborted the transfer of {index:#06x}:{sub}: {code}")]
    Aborted {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Why.
        code: AbortCode,
    },
    /// The server answered out of protocol; the client aborts with `code`.
    #[error("protocol error: {reason} (aborting with {code})")]
    Protocol {
        /// What was wrong.
        reason: &'static str,
        /// The abort the client should send.
        code: AbortCode,
    },
}

/// The next step of a client transfer.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Step {
    /// Send this request and wait for the answer.
    Send(ClientRequest),
    /// The transfer is complete (for an upload: the data read).
    Done(Vec<u8>),
}

/// A write (SDO download) from the client side: feed it the server's responses.
#[derive(Debug, Clone)]
pub struct Download {
    index: u16,
    sub: u8,
    data: Vec<u8>,
    sent: usize,
    toggle: bool,
    started: bool,
    /// The segments have begun (the first one sent, if only an empty one).
    segmenting: bool,
}

impl Download {
    /// A write of `data` to `index`/`sub`; expedited when it fits in 4 bytes.
    pub fn new(index: u16, sub: u8, data: Vec<u8>) -> Download {
        Download {
            index,
            sub,
            data,
            sent: 0,
            toggle: false,
            started: false,
            segmenting: false,
        }
    }

    /// The first request.
    pub fn start(&mut self) -> ClientRequest {
        self.started = true;
        let data = if (1..=4).contains(&self.data.len()) {
            Initiate::Expedited(self.data.clone())
        } else {
            Initiate::Segmented(Some(self.data.len() as u32))
        };
        ClientRequest::InitiateDownload {
            index: self.index,
            sub: self.sub,
            data,
        }
    }

    fn next_segment(&mut self) -> ClientRequest {
        self.segmenting = true;
        let end = (self.sent + 7).min(self.data.len());
        let chunk = self.data[self.sent..end].to_vec();
        let req = ClientRequest::DownloadSegment {
            toggle: self.toggle,
            data: chunk,
            last: end == self.data.len(),
        };
        self.sent = end;
        req
    }

    /// Consumes a server response; returns the next step.
    pub fn on_response(&mut self, resp: &ServerResponse) -> Result<Step, SdoError> {
        let protocol = |reason| SdoError::Protocol {
            reason,
            code: AbortCode::BAD_COMMAND,
        };
        match resp {
            ServerResponse::Abort { index, sub, code } => Err(SdoError::Aborted {
                index: *index,
                sub: *sub,
                code: *code,
            }),
            ServerResponse::DownloadInitiated { index, sub }
                if self.started && !self.segmenting =>
            {
                if (*index, *sub) != (self.index, self.sub) {
                    return Err(protocol("answer for another object"));
                }
                if (1..=4).contains(&self.data.len()) {
                    Ok(Step::Done(Vec::new()))
                } else {
                    Ok(Step::Send(self.next_segment()))
                }
            }
            ServerResponse::DownloadSegmentAck { toggle } if self.segmenting => {
                if *toggle != self.toggle {
                    return Err(SdoError::Protocol {
                        reason: "toggle bit not alternated",
                        code: AbortCode::TOGGLE,
                    });
                }
                self.toggle = !self.toggle;
                if self.sent == self.data.len() {
                    Ok(Step::Done(Vec::new()))
                } else {
                    Ok(Step::Send(self.next_segment()))
                }
            }
            _ => Err(protocol("unexpected response to a download")),
        }
    }
}

/// A read (SDO upload) from the client side: feed it the server's responses.
#[derive(Debug, Clone)]
pub struct Upload {
    index: u16,
    sub: u8,
    data: Vec<u8>,
    size: Option<u32>,
    toggle: bool,
    segmented: bool,
    /// Largest size accepted, so a hostile server cannot make us grow without bound.
    max_size: usize,
}

impl Upload {
    /// A read of `index`/`sub`, refusing more than `max_size` bytes.
    pub fn new(index: u16, sub: u8, max_size: usize) -> Upload {
        Upload {
            index,
            sub,
            data: Vec::new(),
            size: None,
            toggle: false,
            segmented: false,
            max_size,
        }
    }

    /// The first request.
    pub fn start(&self) -> ClientRequest {
        ClientRequest::InitiateUpload {
            index: self.index,
            sub: self.sub,
        }
    }

    /// Consumes a server response; returns the next step.
    pub fn on_response(&mut self, resp: &ServerResponse) -> Result<Step, SdoError> {
        let protocol = |reason| SdoError::Protocol {
            reason,
            code: AbortCode::BAD_COMMAND,
        };
        match resp {
            ServerResponse::Abort { index, sub, code } => Err(SdoError::Aborted {
                index: *index,
                sub: *sub,
                code: *code,
            }),
            ServerResponse::UploadInitiated { index, sub, data } if !self.segmented => {
                if (*index, *sub) != (self.index, self.sub) {
                    return Err(protocol("answer for another object"));
                }
                match data {
                    Initiate::Expedited(bytes) => Ok(Step::Done(bytes.clone())),
                    Initiate::Segmented(size) => {
                        if size.is_some_and(|s| s as usize > self.max_size) {
                            return Err(SdoError::Protocol {
                                reason: "object larger than accepted",
                                code: AbortCode::OUT_OF_MEMORY,
                            });
                        }
                        self.segmented = true;
                        self.size = *size;
                        Ok(Step::Send(ClientRequest::UploadSegment { toggle: false }))
                    }
                }
            }
            ServerResponse::UploadSegment { toggle, data, last } if self.segmented => {
                if *toggle != self.toggle {
                    return Err(SdoError::Protocol {
                        reason: "toggle bit not alternated",
                        code: AbortCode::TOGGLE,
                    });
                }
                if self.data.len() + data.len() > self.max_size {
                    return Err(SdoError::Protocol {
                        reason: "object larger than accepted",
                        code: AbortCode::OUT_OF_MEMORY,
                    });
                }
                self.data.extend_from_slice(data);
                self.toggle = !self.toggle;
                if *last {
                    if self.size.is_some_and(|s| s as usize != self.data.len()) {
                        return Err(SdoError::Protocol {
                            reason: "size indicated and data received differ",
                            code: AbortCode::LENGTH_MISMATCH,
                        });
                    }
                    Ok(Step::Done(std::mem::take(&mut self.data)))
                } else {
                    Ok(Step::Send(ClientRequest::UploadSegment {
                        toggle: self.toggle,
                    }))
                }
            }
            _ => Err(protocol("unexpected response to an upload")),
        }
    }
}

/// The object dictionary an SDO [`Server`] serves. Its implementation decides what exists,
/// who may read and write it, and what a write does.
pub trait Dictionary {
    /// The value of `index`/`sub`, for an upload.
    fn upload(&mut self, index: u16, sub: u8) -> Result<Vec<u8>, AbortCode>;
    /// Whether a segmented write of `size` bytes (when indicated) to `index`/`sub` may begin
    /// (the object exists and is writable); the data follows.
    fn may_download(&mut self, index: u16, sub: u8, size: Option<u32>) -> Result<(), AbortCode>;
    /// Writes `data` to `index`/`sub`.
    fn download(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode>;
}

/// A segmented transfer the server has under way.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Transfer {
    Upload {
        index: u16,
        sub: u8,
        data: Vec<u8>,
        toggle: bool,
    },
    Download {
        index: u16,
        sub: u8,
        size: Option<u32>,
        data: Vec<u8>,
        toggle: bool,
    },
}

/// The server side of SDO as a pure state machine: one request in, at most one response out,
/// over a [`Dictionary`]. Expedited and segmented transfers in both directions, toggle and
/// size checks, the client's abort (ends the transfer, no answer), and block transfers
/// refused with "command specifier not valid" (0x05040001).
#[derive(Debug, Clone)]
pub struct Server {
    transfer: Option<Transfer>,
    /// Largest segmented download taken, so a client cannot make the server grow without
    /// bound.
    max_size: usize,
}

impl Default for Server {
    fn default() -> Server {
        Server::new()
    }
}

impl Server {
    /// A server with no transfer under way, taking writes of up to 4096 bytes.
    pub fn new() -> Server {
        Server {
            transfer: None,
            max_size: 4096,
        }
    }

    /// Forgets a transfer under way (NMT reset).
    pub fn reset(&mut self) {
        self.transfer = None;
    }

    /// True while a segmented transfer is under way.
    pub fn busy(&self) -> bool {
        self.transfer.is_some()
    }

    /// Ends the transfer under way with `code`, naming its object (0/0 when none).
    fn abort(&mut self, code: AbortCode) -> ServerResponse {
        let (index, sub) = match self.transfer.take() {
            Some(Transfer::Upload { index, sub, .. } | Transfer::Download { index, sub, .. }) => {
                (index, sub)
            }
            None => (0, 0),
        };
        ServerResponse::Abort { index, sub, code }
    }

    /// Serves one frame received on the server's COB-ID (0x600 + node), as [`on_request`]
    /// does once decoded; an 8-byte client frame whose command specifier is none of CiA
    /// 301's (7) ends any transfer under way with "command specifier not valid or unknown"
    /// (0x05040001), naming its object (0/0 when none). Other frames that are no request
    /// (too short, another COB-ID) get no answer.
    ///
    /// [`on_request`]: Server::on_request
    pub fn on_frame(
        &mut self,
        frame: &CanFrame,
        od: &mut impl Dictionary,
    ) -> Option<ServerResponse> {
        match ClientRequest::decode(frame) {
            Ok((_, req)) => self.on_request(&req, od),
            Err(_)
                if node_of(frame, Function::SdoRx).is_ok()
                    && frame.data_at_least(8).is_ok_and(|d| d[0] >> 5 == 7) =>
            {
                Some(self.abort(AbortCode::BAD_COMMAND))
            }
            Err(_) => None,
        }
    }

    /// Serves one request; `None` when nothing is to be answered (a client's abort).
    pub fn on_request(
        &mut self,
        req: &ClientRequest,
        od: &mut impl Dictionary,
    ) -> Option<ServerResponse> {
        let abort = |index, sub, code| Some(ServerResponse::Abort { index, sub, code });
        match req {
            ClientRequest::InitiateUpload { index, sub } => {
                // A new initiate ends whatever was under way.
                self.transfer = None;
                let (index, sub) = (*index, *sub);
                let data = match od.upload(index, sub) {
                    Ok(d) => d,
                    Err(code) => return abort(index, sub, code),
                };
                if (1..=4).contains(&data.len()) {
                    return Some(ServerResponse::UploadInitiated {
                        index,
                        sub,
                        data: Initiate::Expedited(data),
                    });
                }
                let size = data.len() as u32;
                self.transfer = Some(Transfer::Upload {
                    index,
                    sub,
                    data,
                    toggle: false,
                });
                Some(ServerResponse::UploadInitiated {
                    index,
                    sub,
                    data: Initiate::Segmented(Some(size)),
                })
            }
            ClientRequest::UploadSegment { toggle } => {
                let Some(Transfer::Upload {
                    data,
                    toggle: expected,
                    ..
                }) = self.transfer.as_mut()
                else {
                    return Some(self.abort(AbortCode::BAD_COMMAND));
                };
                if toggle != expected {
                    return Some(self.abort(AbortCode::TOGGLE));
                }
                *expected = !*expected;
                let n = data.len().min(7);
                let chunk: Vec<u8> = data.drain(..n).collect();
                let last = data.is_empty();
                if last {
                    self.transfer = None;
                }
                Some(ServerResponse::UploadSegment {
                    toggle: *toggle,
                    data: chunk,
                    last,
                })
            }
            ClientRequest::InitiateDownload { index, sub, data } => {
                self.transfer = None;
                let (index, sub) = (*index, *sub);
                match data {
                    Initiate::Expedited(bytes) => match od.download(index, sub, bytes) {
                        Ok(()) => Some(ServerResponse::DownloadInitiated { index, sub }),
                        Err(code) => abort(index, sub, code),
                    },
                    Initiate::Segmented(size) => {
                        if size.is_some_and(|s| s as usize > self.max_size) {
                            return abort(index, sub, AbortCode::OUT_OF_MEMORY);
                        }
                        if let Err(code) = od.may_download(index, sub, *size) {
                            return abort(index, sub, code);
                        }
                        self.transfer = Some(Transfer::Download {
                            index,
                            sub,
                            size: *size,
                            data: Vec::new(),
                            toggle: false,
                        });
                        Some(ServerResponse::DownloadInitiated { index, sub })
                    }
                }
            }
            ClientRequest::DownloadSegment { toggle, data, last } => {
                let max = self.max_size;
                let Some(Transfer::Download {
                    data: got,
                    toggle: expected,
                    ..
                }) = self.transfer.as_mut()
                else {
                    return Some(self.abort(AbortCode::BAD_COMMAND));
                };
                if toggle != expected {
                    return Some(self.abort(AbortCode::TOGGLE));
                }
                if got.len() + data.len() > max {
                    return Some(self.abort(AbortCode::OUT_OF_MEMORY));
                }
                *expected = !*expected;
                got.extend_from_slice(data);
                if *last {
                    let Some(Transfer::Download {
                        index,
                        sub,
                        size,
                        data,
                        ..
                    }) = self.transfer.take()
                    else {
                        unreachable!("a download is under way")
                    };
                    if size.is_some_and(|s| s as usize != data.len()) {
                        return abort(index, sub, AbortCode::LENGTH_MISMATCH);
                    }
                    if let Err(code) = od.download(index, sub, &data) {
                        return abort(index, sub, code);
                    }
                }
                Some(ServerResponse::DownloadSegmentAck { toggle: *toggle })
            }
            ClientRequest::Block { index, sub, .. } => {
                self.transfer = None;
                abort(*index, *sub, AbortCode::BAD_COMMAND)
            }
            // The client gave up: the transfer ends, and CiA 301 has no answer to an abort.
            ClientRequest::Abort { .. } => {
                self.transfer = None;
                None
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn n(id: u8) -> NodeId {
        NodeId::new(id).unwrap()
    }

    #[test]
    fn golden_expedited_frames() {
        // Read the statusword 0x6041:00 of node 1: 40 41 60 00 00 00 00 00 on 0x601.
        let f = ClientRequest::InitiateUpload {
            index: 0x6041,
            sub: 0,
        }
        .encode(n(1))
        .unwrap();
        assert_eq!(
            (f.raw_id(), f.data()),
            (0x601, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0][..])
        );
        // The answer with a 2-byte value 0x0237: 4B 41 60 00 37 02 00 00 on 0x581.
        let f = CanFrame::standard(0x581, &[0x4b, 0x41, 0x60, 0, 0x37, 0x02, 0, 0]).unwrap();
        let (node, resp) = ServerResponse::decode(&f).unwrap();
        assert_eq!(node, n(1));
        assert_eq!(
            resp,
            ServerResponse::UploadInitiated {
                index: 0x6041,
                sub: 0,
                data: Initiate::Expedited(vec![0x37, 0x02])
            }
        );
        assert_eq!(resp.encode(n(1)).unwrap(), f);
        // Write controlword 0x6040:00 = 0x000F: 2B 40 60 00 0F 00 00 00.
        let mut dl = Download::new(0x6040, 0, vec![0x0f, 0x00]);
        let f = dl.start().encode(n(1)).unwrap();
        assert_eq!(f.data(), [0x2b, 0x40, 0x60, 0x00, 0x0f, 0x00, 0x00, 0x00]);
        // A 4-byte write uses 0x23, a 1-byte write 0x2F.
        assert_eq!(
            Download::new(0x1017, 0, vec![0xe8, 3, 0, 0])
                .start()
                .encode(n(1))
                .unwrap()
                .data()[0],
            0x23
        );
        assert_eq!(
            Download::new(0x6060, 0, vec![7])
                .start()
                .encode(n(1))
                .unwrap()
                .data()[0],
            0x2f
        );
        // The server's acknowledgement: 60 40 60 00 ...
        let ack = ServerResponse::DownloadInitiated {
            index: 0x6040,
            sub: 0,
        };
        assert_eq!(
            ack.encode(n(1)).unwrap().data()[..4],
            [0x60, 0x40, 0x60, 0x00]
        );
        assert_eq!(dl.on_response(&ack).unwrap(), Step::Done(vec![]));
    }

    #[test]
    fn abort_frames_are_named() {
        let f =
            CanFrame::standard(0x585, &[0x80, 0x00, 0x20, 0x01, 0x00, 0x00, 0x02, 0x06]).unwrap();
        let (_, resp) = ServerResponse::decode(&f).unwrap();
        let ServerResponse::Abort { index, sub, code } = resp else {
            panic!("not an abort")
        };
        assert_eq!((index, sub, code), (0x2000, 1, AbortCode::NO_OBJECT));
        assert_eq!(
            code.describe(),
            "object does not exist in the object dictionary"
        );
        let mut up = Upload::new(0x2000, 1, 64);
        assert!(matches!(
            up.on_response(&resp),
            Err(SdoError::Aborted {
                code: AbortCode::NO_OBJECT,
                ..
            })
        ));
    }

    /// A tiny in-test server answering segmented transfers, to run both state machines.
    fn serve(obj: &mut Vec<u8>, req: &ClientRequest, toggle_bug: bool) -> ServerResponse {
        match req {
            ClientRequest::InitiateDownload { index, sub, data } => {
                if let Initiate::Expedited(b) = data {
                    *obj = b.clone();
                } else {
                    obj.clear();
                }
                ServerResponse::DownloadInitiated {
                    index: *index,
                    sub: *sub,
                }
            }
            ClientRequest::DownloadSegment { toggle, data, .. } => {
                obj.extend_from_slice(data);
                ServerResponse::DownloadSegmentAck {
                    toggle: *toggle ^ toggle_bug,
                }
            }
            ClientRequest::InitiateUpload { index, sub } => ServerResponse::UploadInitiated {
                index: *index,
                sub: *sub,
                data: if obj.len() <= 4 {
                    Initiate::Expedited(obj.clone())
                } else {
                    Initiate::Segmented(Some(obj.len() as u32))
                },
            },
            ClientRequest::UploadSegment { toggle } => {
                let take = obj.len().min(7);
                let chunk: Vec<u8> = obj.drain(..take).collect();
                ServerResponse::UploadSegment {
                    toggle: *toggle,
                    data: chunk,
                    last: obj.is_empty(),
                }
            }
            ClientRequest::Abort { .. } | ClientRequest::Block { .. } => unreachable!(),
        }
    }

    #[test]
    fn segmented_round_trip_through_frames() {
        let text = b"Elmo Gold Twitter G-TWI25/100SE, firmware 01.01.16".to_vec();
        let mut obj = Vec::new();
        let mut dl = Download::new(0x1008, 0, text.clone());
        let mut req = dl.start();
        let mut frames = 0;
        loop {
            // Every message crosses as a real frame.
            let (_, req2) = ClientRequest::decode(&req.encode(n(9)).unwrap()).unwrap();
            assert_eq!(req2, req);
            let resp = serve(&mut obj, &req2, false);
            let (_, resp2) = ServerResponse::decode(&resp.encode(n(9)).unwrap()).unwrap();
            frames += 1;
            match dl.on_response(&resp2).unwrap() {
                Step::Send(r) => req = r,
                Step::Done(_) => break,
            }
        }
        assert_eq!(obj, text);
        assert_eq!(frames, 1 + text.len().div_ceil(7));
        let mut up = Upload::new(0x1008, 0, 1024);
        let mut req = up.start();
        let got = loop {
            let resp = serve(&mut obj, &req, false);
            match up.on_response(&resp).unwrap() {
                Step::Send(r) => req = r,
                Step::Done(d) => break d,
            }
        };
        assert_eq!(got, text);
    }

    #[test]
    fn toggle_errors_and_size_limits() {
        let mut obj = Vec::new();
        let mut dl = Download::new(0x1008, 0, vec![1; 20]);
        let r = dl.start();
        let resp = serve(&mut obj, &r, true);
        let Step::Send(seg) = dl.on_response(&resp).unwrap() else {
            panic!()
        };
        let resp = serve(&mut obj, &seg, true);
        assert!(matches!(
            dl.on_response(&resp),
            Err(SdoError::Protocol {
                code: AbortCode::TOGGLE,
                ..
            })
        ));
        let mut up = Upload::new(0x1008, 0, 8);
        let big = ServerResponse::UploadInitiated {
            index: 0x1008,
            sub: 0,
            data: Initiate::Segmented(Some(1 << 30)),
        };
        assert!(up.on_response(&big).is_err());
        let mut up = Upload::new(0x1008, 0, 8);
        let other = ServerResponse::UploadInitiated {
            index: 0x1009,
            sub: 0,
            data: Initiate::Expedited(vec![1]),
        };
        assert!(up.on_response(&other).is_err());
    }

    /// A dictionary of plain values: 0x1000:0 read-only, 0x1008:0 text, 0x2000:1 a u16.
    struct Od(std::collections::BTreeMap<(u16, u8), (bool, Vec<u8>)>);

    impl Od {
        fn new() -> Od {
            let mut m = std::collections::BTreeMap::new();
            m.insert((0x1000, 0), (false, vec![0x92, 1, 2, 0]));
            m.insert((0x1008, 0), (true, b"a name longer than seven".to_vec()));
            m.insert((0x2000, 1), (true, vec![0, 0]));
            Od(m)
        }
        fn entry(&self, index: u16, sub: u8) -> Result<&(bool, Vec<u8>), AbortCode> {
            self.0
                .get(&(index, sub))
                .ok_or(if self.0.keys().any(|(i, _)| *i == index) {
                    AbortCode::NO_SUBINDEX
                } else {
                    AbortCode::NO_OBJECT
                })
        }
    }

    impl Dictionary for Od {
        fn upload(&mut self, index: u16, sub: u8) -> Result<Vec<u8>, AbortCode> {
            Ok(self.entry(index, sub)?.1.clone())
        }
        fn may_download(&mut self, index: u16, sub: u8, _: Option<u32>) -> Result<(), AbortCode> {
            match self.entry(index, sub)? {
                (true, _) => Ok(()),
                _ => Err(AbortCode::READ_ONLY),
            }
        }
        fn download(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
            self.may_download(index, sub, None)?;
            let e = self.0.get_mut(&(index, sub)).expect("checked");
            if index != 0x1008 && e.1.len() != data.len() {
                return Err(AbortCode::LENGTH_MISMATCH);
            }
            e.1 = data.to_vec();
            Ok(())
        }
    }

    /// Runs a client transfer against `server` through real frames; the data, or the abort.
    fn run(
        server: &mut Server,
        od: &mut Od,
        mut first: ClientRequest,
        mut step: impl FnMut(&ServerResponse) -> Result<Step, SdoError>,
    ) -> Result<Vec<u8>, SdoError> {
        loop {
            let (_, req) = ClientRequest::decode(&first.encode(n(3)).unwrap()).unwrap();
            let resp = server.on_request(&req, od).expect("answered");
            let (_, resp) = ServerResponse::decode(&resp.encode(n(3)).unwrap()).unwrap();
            match step(&resp)? {
                Step::Send(r) => first = r,
                Step::Done(d) => return Ok(d),
            }
        }
    }

    #[test]
    fn the_server_serves_the_client_state_machines() {
        let (mut server, mut od) = (Server::new(), Od::new());
        let up = |server: &mut Server, od: &mut Od, index, sub| {
            let mut u = Upload::new(index, sub, 256);
            let r = u.start();
            run(server, od, r, |resp| u.on_response(resp))
        };
        assert_eq!(
            up(&mut server, &mut od, 0x1000, 0).unwrap(),
            [0x92, 1, 2, 0]
        );
        assert_eq!(
            up(&mut server, &mut od, 0x1008, 0).unwrap(),
            b"a name longer than seven"
        );
        // A segmented write, then an expedited one, read back.
        let text = b"twenty bytes of text".to_vec();
        let mut d = Download::new(0x1008, 0, text.clone());
        let r = d.start();
        run(&mut server, &mut od, r, |resp| d.on_response(resp)).unwrap();
        assert_eq!(up(&mut server, &mut od, 0x1008, 0).unwrap(), text);
        let mut d = Download::new(0x2000, 1, vec![7, 0]);
        let r = d.start();
        run(&mut server, &mut od, r, |resp| d.on_response(resp)).unwrap();
        assert_eq!(od.0[&(0x2000, 1)].1, [7, 0]);
        assert!(!server.busy());
    }

    #[test]
    fn the_server_aborts_as_cia_301_says() {
        let (mut server, mut od) = (Server::new(), Od::new());
        let aborted = |r: Option<ServerResponse>| match r {
            Some(ServerResponse::Abort { index, sub, code }) => (index, sub, code),
            other => panic!("{other:?}"),
        };
        let upload = |index, sub| ClientRequest::InitiateUpload { index, sub };
        // An absent object, an absent sub-index of an existing one.
        assert_eq!(
            aborted(server.on_request(&upload(0x2222, 0), &mut od)),
            (0x2222, 0, AbortCode::NO_OBJECT)
        );
        assert_eq!(
            aborted(server.on_request(&upload(0x2000, 2), &mut od)),
            (0x2000, 2, AbortCode::NO_SUBINDEX)
        );
        // A write to a read-only object, expedited and segmented.
        let write = |data| ClientRequest::InitiateDownload {
            index: 0x1000,
            sub: 0,
            data,
        };
        assert_eq!(
            aborted(server.on_request(&write(Initiate::Expedited(vec![1])), &mut od)).2,
            AbortCode::READ_ONLY
        );
        assert_eq!(
            aborted(server.on_request(&write(Initiate::Segmented(Some(9))), &mut od)).2,
            AbortCode::READ_ONLY
        );
        // A segment with no transfer under way; a block transfer.
        assert_eq!(
            aborted(server.on_request(&ClientRequest::UploadSegment { toggle: false }, &mut od)),
            (0, 0, AbortCode::BAD_COMMAND)
        );
        let block = ClientRequest::Block {
            download: false,
            index: 0x1008,
            sub: 0,
        };
        let (_, block) = ClientRequest::decode(&block.encode(n(3)).unwrap()).unwrap();
        assert_eq!(
            aborted(server.on_request(&block, &mut od)),
            (0x1008, 0, AbortCode::BAD_COMMAND)
        );
        // A wrong toggle ends the transfer, naming it.
        server.on_request(&upload(0x1008, 0), &mut od).unwrap();
        assert_eq!(
            aborted(server.on_request(&ClientRequest::UploadSegment { toggle: true }, &mut od)),
            (0x1008, 0, AbortCode::TOGGLE)
        );
        assert!(!server.busy());
        // A segmented write whose data is shorter than the size it announced.
        let w = ClientRequest::InitiateDownload {
            index: 0x1008,
            sub: 0,
            data: Initiate::Segmented(Some(10)),
        };
        server.on_request(&w, &mut od).unwrap();
        let seg = ClientRequest::DownloadSegment {
            toggle: false,
            data: vec![1, 2, 3],
            last: true,
        };
        assert_eq!(
            aborted(server.on_request(&seg, &mut od)),
            (0x1008, 0, AbortCode::LENGTH_MISMATCH)
        );
        // The client's abort ends a transfer and gets no answer.
        server.on_request(&upload(0x1008, 0), &mut od).unwrap();
        let abort = ClientRequest::Abort {
            index: 0x1008,
            sub: 0,
            code: AbortCode::GENERAL,
        };
        assert_eq!(server.on_request(&abort, &mut od), None);
        assert!(!server.busy());
    }

    proptest::proptest! {
        #[test]
        fn any_8_bytes_decode_without_panic(d in proptest::collection::vec(proptest::num::u8::ANY, 0..=8)) {
            let f = CanFrame::standard(0x581, &d).unwrap();
            let _ = ServerResponse::decode(&f);
            let f = CanFrame::standard(0x601, &d).unwrap();
            if let Ok((node, req)) = ClientRequest::decode(&f) {
                // What decodes re-encodes to a frame that decodes the same.
                if let Ok(g) = req.encode(node) {
                    proptest::prop_assert_eq!(ClientRequest::decode(&g).unwrap().1, req);
                }
            }
        }
    }
}
