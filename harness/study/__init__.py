"""What a study asks for: the study file and its one schema, the scene catalogue, plugins, claims, the analyses a
group can ask for and the task each cell computes."""
