"""What the pictures of a results directory draw, read from pyvista's objects instead of
pixels: ``python -P picture_probe.py RESULTS FACTOR DIM`` runs pictures.draw_all with its
writer replaced by a recorder and prints one JSON line {picture: {"bars": {title: [low,
high]}, "texts": [...], "coloured": [scalar ranges of the meshes coloured by a field],
"plain": the number of meshes in one colour, "labels": {title: the bar's number of labels,
their format, font size and the bar's width in pixels, its range}}}.  A process of its
own: VTK and dolfinx must not share one (app/post/pictures.py)."""
import json
import sys
from pathlib import Path


def describe(plotter) -> dict:
    """The scalar bars, texts and meshes of a plotter (all its renderers)."""
    import vtk
    bars = {title: list(bar.GetLookupTable().GetRange())
            for title, bar in plotter.scalar_bars.items()}
    texts, coloured, plain, labels = [], [], 0, {}
    for renderer in plotter.renderers:
        viewport = renderer.GetViewport()
        for actor in renderer.actors.values():
            if isinstance(actor, vtk.vtkScalarBarActor):
                low, high = actor.GetLookupTable().GetRange()
                labels[actor.GetTitle()] = {
                    "n": actor.GetNumberOfLabels(), "format": actor.GetLabelFormat(),
                    "font_px": actor.GetLabelTextProperty().GetFontSize(),
                    "width_px": actor.GetWidth() * (viewport[2] - viewport[0])
                    * plotter.window_size[0], "range": [low, high]}
            elif isinstance(actor, vtk.vtkCornerAnnotation):
                texts += [actor.GetText(i) for i in range(8) if actor.GetText(i)]
            elif isinstance(actor, vtk.vtkTextActor):
                texts.append(actor.GetInput())
            elif hasattr(actor, "GetMapper") and actor.GetMapper() is not None:
                mapper = actor.GetMapper()
                if mapper.GetScalarVisibility() and mapper.GetInput() is not None \
                        and mapper.GetInput().GetNumberOfCells() > 0:
                    coloured.append(list(mapper.GetScalarRange()))
                else:
                    plain += 1
    return {"bars": bars, "texts": texts, "coloured": coloured, "plain": plain,
            "labels": labels}


def main() -> None:
    from vpcontact.post import pictures
    out, factor, dim = Path(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3])
    drawn = {}

    def record(plotter, path):
        drawn[Path(path).name.replace(".tmp", "").lstrip(".")] = describe(plotter)
        pictures_save(plotter, path)
    pictures_save = pictures._save
    pictures._save = record
    pictures.draw_all(out, factor, dim)
    print(json.dumps(drawn))


if __name__ == "__main__":
    main()
