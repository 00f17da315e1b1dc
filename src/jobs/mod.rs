//! Jobs: the transfer worker, a client of the engine like the CLI and the app. It runs MeshMatch
//! solves on its own thread and streams progress over a crossbeam channel.

pub mod worker;
