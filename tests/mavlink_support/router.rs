//! A UDP router in front of several autopilots, as mavlink-router or a telemetry radio puts them
//! behind one endpoint: Kestrel sees one peer and tells the vehicles apart by system id.
//!
//! In: the UDP ports the fake's vehicles send to (each vehicle's `udpin` connection string) and
//! Kestrel's `udpin` port. Out: every datagram from a vehicle goes to Kestrel from one socket;
//! every datagram from Kestrel goes to every vehicle heard so far (each autopilot takes only what
//! names its system, as real ones do). Datagrams are copied whole, never parsed.

use std::net::{SocketAddr, UdpSocket};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// Each vehicle's socket and the address it was last heard from.
type Vehicles = Arc<Mutex<Vec<(Arc<UdpSocket>, Option<SocketAddr>)>>>;

pub struct UdpRouter {
    /// Datagrams copied each way (vehicles to Kestrel, Kestrel to vehicles).
    pub counts: Arc<Mutex<(u64, u64)>>,
}

impl UdpRouter {
    /// `vehicle_connections`: the `udpin:127.0.0.1:PORT` strings the fake's vehicles send to.
    pub fn start(vehicle_connections: &[String], kestrel_port: u16) -> Self {
        let to_kestrel = Arc::new(UdpSocket::bind("127.0.0.1:0").unwrap());
        let kestrel: SocketAddr = format!("127.0.0.1:{kestrel_port}").parse().unwrap();
        let counts = Arc::new(Mutex::new((0, 0)));
        let vehicles: Vehicles = Arc::new(Mutex::new(Vec::new()));
        for connection in vehicle_connections {
            let port = connection.rsplit(':').next().unwrap();
            let socket = Arc::new(UdpSocket::bind(format!("127.0.0.1:{port}")).unwrap());
            socket
                .set_read_timeout(Some(Duration::from_millis(200)))
                .unwrap();
            let index = {
                let mut v = vehicles.lock().unwrap();
                v.push((socket.clone(), None));
                v.len() - 1
            };
            let (out, list, counts) = (to_kestrel.clone(), vehicles.clone(), counts.clone());
            std::thread::spawn(move || {
                let mut buf = [0u8; 2048];
                loop {
                    let Ok((n, from)) = socket.recv_from(&mut buf) else {
                        continue;
                    };
                    list.lock().unwrap()[index].1 = Some(from);
                    if out.send_to(&buf[..n], kestrel).is_ok() {
                        counts.lock().unwrap().0 += 1;
                    }
                }
            });
        }
        let (list, c) = (vehicles.clone(), counts.clone());
        std::thread::spawn(move || {
            let mut buf = [0u8; 2048];
            while let Ok((n, _)) = to_kestrel.recv_from(&mut buf) {
                for (socket, heard) in list.lock().unwrap().iter() {
                    if let Some(addr) = heard {
                        let _ = socket.send_to(&buf[..n], addr);
                    }
                }
                c.lock().unwrap().1 += 1;
            }
        });
        UdpRouter { counts }
    }
}
