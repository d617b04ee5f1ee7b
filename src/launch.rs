//! How this process was started: alone, or as one of several processes of an MPI launcher
//! (`mpirun`, `mpiexec`), told by the environment variables the launchers set.

/// This process's place among the processes an MPI launcher started.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Launched {
    /// This process's rank, 0-based.
    pub rank: usize,
    /// How many processes the launcher started.
    pub size: usize,
}

/// The (size, rank) variables of the launchers: Open MPI's, and the PMI ones of MPICH and
/// Intel MPI (Hydra). Slurm's job variables are not among them: they are set in a batch
/// script for one process too.
const LAUNCHER_VARIABLES: [(&str, &str); 2] = [
    ("OMPI_COMM_WORLD_SIZE", "OMPI_COMM_WORLD_RANK"),
    ("PMI_SIZE", "PMI_RANK"),
];

/// The launcher's processes this one belongs to, when a launcher started more than one
/// (`None` for a process started alone or as the only one).
pub fn launched_processes() -> Option<Launched> {
    launched_by(|name| std::env::var(name).ok())
}

fn launched_by(var: impl Fn(&str) -> Option<String>) -> Option<Launched> {
    let number = |name: &str| var(name).and_then(|v| v.trim().parse::<usize>().ok());
    LAUNCHER_VARIABLES.iter().find_map(|&(size, rank)| {
        let size = number(size).filter(|&n| n > 1)?;
        Some(Launched {
            rank: number(rank).unwrap_or(0),
            size,
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env<'a>(pairs: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |name| {
            pairs
                .iter()
                .find(|(n, _)| *n == name)
                .map(|(_, v)| v.to_string())
        }
    }

    #[test]
    fn launchers_are_told_by_their_variables() {
        assert_eq!(launched_by(env(&[])), None);
        // One process of a launcher runs as a plain one.
        assert_eq!(launched_by(env(&[("OMPI_COMM_WORLD_SIZE", "1")])), None);
        let open_mpi = [("OMPI_COMM_WORLD_SIZE", "2"), ("OMPI_COMM_WORLD_RANK", "1")];
        assert_eq!(
            launched_by(env(&open_mpi)),
            Some(Launched { rank: 1, size: 2 })
        );
        let hydra = [("PMI_SIZE", "4"), ("PMI_RANK", "0")];
        assert_eq!(
            launched_by(env(&hydra)),
            Some(Launched { rank: 0, size: 4 })
        );
        assert_eq!(launched_by(env(&[("SLURM_NTASKS", "3")])), None);
    }
}
