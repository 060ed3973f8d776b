//! SDO: the service data protocol (client 0x600 + node, server 0x580 + node), expedited and
//! segmented transfers, abort codes, and client-side transfer state machines.

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
            ServerResponse::DownloadInitiated { index, sub } if self.started && self.sent == 0 => {
                if (*index, *sub) != (self.index, self.sub) {
                    return Err(protocol("answer for another object"));
                }
                if (1..=4).contains(&self.data.len()) {
                    Ok(Step::Done(Vec::new()))
                } else {
                    Ok(Step::Send(self.next_segment()))
                }
            }
            ServerResponse::DownloadSegmentAck { toggle } if self.sent > 0 => {
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
                                code: AbortCode(0x0504_0005),
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
                        code: AbortCode(0x0504_0005),
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
            ClientRequest::Abort { .. } => unreachable!(),
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
