//! A packet capture on the private network namespace's loopback, for the wire checks of the
//! security tests (what a peer on the cell's network would see): a raw `AF_PACKET` socket bound
//! to `lo` takes every frame, both ways, until [`Capture::stop`]; the frames can be searched for
//! a message's bytes and written as a pcap file that Wireshark or tcpdump reads.
//!
//! Only inside the namespace (`../shared/tools/netns-run`): there the test is root over its own
//! network and `lo` carries only the test's traffic.

use std::io::Write;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

/// A running capture: one thread reading the socket.
pub struct Capture {
    stop: Arc<AtomicBool>,
    thread: JoinHandle<Vec<Vec<u8>>>,
}

/// `ETH_P_ALL` in network byte order, as `socket(2)` and `sockaddr_ll` take it.
fn all_protocols() -> u16 {
    (libc::ETH_P_ALL as u16).to_be()
}

impl Capture {
    /// Starts capturing every frame on `lo`; the socket's error where it cannot (outside a
    /// namespace where the test is not root).
    pub fn start() -> std::io::Result<Capture> {
        // SAFETY: plain socket calls on a descriptor this function owns; every struct passed is
        // fully initialised and its size is given.
        let fd = unsafe { libc::socket(libc::AF_PACKET, libc::SOCK_RAW, all_protocols() as i32) };
        if fd < 0 {
            return Err(std::io::Error::last_os_error());
        }
        let index = unsafe { libc::if_nametoindex(c"lo".as_ptr()) };
        let mut addr: libc::sockaddr_ll = unsafe { std::mem::zeroed() };
        addr.sll_family = libc::AF_PACKET as u16;
        addr.sll_protocol = all_protocols();
        addr.sll_ifindex = index as i32;
        let timeout = libc::timeval {
            tv_sec: 0,
            tv_usec: 100_000,
        };
        let buffer: libc::c_int = 32 << 20;
        let ok = unsafe {
            libc::bind(
                fd,
                &addr as *const libc::sockaddr_ll as *const libc::sockaddr,
                std::mem::size_of::<libc::sockaddr_ll>() as u32,
            ) == 0
                && libc::setsockopt(
                    fd,
                    libc::SOL_SOCKET,
                    libc::SO_RCVTIMEO,
                    &timeout as *const libc::timeval as *const libc::c_void,
                    std::mem::size_of::<libc::timeval>() as u32,
                ) == 0
        };
        if !ok {
            let e = std::io::Error::last_os_error();
            unsafe { libc::close(fd) };
            return Err(e);
        }
        // A larger receive buffer where the kernel allows it: fewer frames lost under a burst.
        unsafe {
            libc::setsockopt(
                fd,
                libc::SOL_SOCKET,
                libc::SO_RCVBUF,
                &buffer as *const libc::c_int as *const libc::c_void,
                std::mem::size_of::<libc::c_int>() as u32,
            )
        };
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let thread = std::thread::spawn(move || {
            let mut frames = Vec::new();
            let mut buf = vec![0u8; 1 << 17];
            while !flag.load(Ordering::Relaxed) {
                let n = unsafe { libc::recv(fd, buf.as_mut_ptr().cast(), buf.len(), 0) };
                if n > 0 {
                    frames.push(buf[..n as usize].to_vec());
                }
            }
            unsafe { libc::close(fd) };
            frames
        });
        Ok(Capture { stop, thread })
    }

    /// Stops the capture and returns its frames (Ethernet headers included), in order.
    pub fn stop(self) -> Vec<Vec<u8>> {
        self.stop.store(true, Ordering::Relaxed);
        self.thread.join().unwrap()
    }
}

/// How many of `frames` hold `needle`.
pub fn frames_with(frames: &[Vec<u8>], needle: &[u8]) -> usize {
    (frames.iter())
        .filter(|f| f.windows(needle.len()).any(|w| w == needle))
        .count()
}

/// Writes `frames` as a pcap file (link type Ethernet, no timestamps) at `path`.
pub fn write_pcap(path: &Path, frames: &[Vec<u8>]) {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    // Magic, version 2.4, no zone, no accuracy, snap length, LINKTYPE_ETHERNET.
    out.write_all(&0xa1b2_c3d4u32.to_le_bytes()).unwrap();
    out.write_all(&2u16.to_le_bytes()).unwrap();
    out.write_all(&4u16.to_le_bytes()).unwrap();
    for v in [0u32, 0, 1 << 18, 1] {
        out.write_all(&v.to_le_bytes()).unwrap();
    }
    for f in frames {
        let len = f.len() as u32;
        for v in [0u32, 0, len, len] {
            out.write_all(&v.to_le_bytes()).unwrap();
        }
        out.write_all(f).unwrap();
    }
}
