"""Result files: curves, genomes, initial conditions and the job summary."""
